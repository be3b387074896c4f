"""The layering rules of DESIGN.md and issue 13, checked on the sources (the CMake configure
step checks the link dependencies): only the API layer touches JSON in the server; wire formats
are not in perception or the simulator library; the run-time filter and the server do not use
the simulator."""

import os
import re

from conftest import ROOT

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.M)


def sources(*dirs, exclude=()):
    for d in dirs:
        for root, _, files in os.walk(os.path.join(ROOT, d)):
            rel = os.path.relpath(root, ROOT)
            if any(rel == e or rel.startswith(e + os.sep) for e in exclude):
                continue
            for f in files:
                if f.endswith((".cc", ".h", ".hpp")):
                    path = os.path.join(root, f)
                    with open(path, encoding="utf-8") as fh:
                        yield os.path.relpath(path, ROOT), fh.read()


def includes(*dirs, exclude=()):
    for path, text in sources(*dirs, exclude=exclude):
        for inc in INCLUDE.findall(text):
            yield path, inc


def test_only_the_api_layer_includes_nlohmann_under_server():
    bad = [(p, i) for p, i in includes("server", exclude=("server/api",)) if "nlohmann" in i]
    assert not bad, bad
    assert any("nlohmann" in i for _, i in includes("server/api"))


def test_the_server_and_the_runtime_filter_do_not_use_the_simulator():
    bad = [(p, i) for p, i in includes("server", "solver/filter/src", "solver/filter/include")
           if i.startswith("npfkct/sim/")]
    assert not bad, bad


def test_wire_formats_live_in_the_api_layer_only():
    wire = re.compile(r"Base64|imdecode|imencode|DecodeCloud|EncodeCloud")
    for d in ("perception/src", "perception/include", "scenarios/src", "scenarios/include",
              "render/src", "render/include"):
        bad = [p for p, text in sources(d) if wire.search(text)]
        assert not bad, bad
    bad = [(p, i) for p, i in includes("scenarios/src", "scenarios/include")
           if i.startswith("npfkct/perception/") or i.startswith("npfkct/api/")]
    assert not bad, bad


def test_lower_modules_never_include_higher_ones():
    order = ["solver", "object_search", "render", "filter", "perception", "sim", "api", "server"]
    homes = {"solver/src": "solver", "solver/include": "solver", "object_search": "object_search",
             "solver/filter/src": "filter", "solver/filter/include": "filter",
             "perception/src": "perception", "perception/include": "perception",
             "scenarios/src": "sim", "scenarios/include": "sim", "server/api": "api",
             "render": "render"}
    allowed = {"solver": {"solver"}, "object_search": {"solver", "object_search"},
               "filter": {"solver", "object_search", "filter"},
               "perception": {"solver", "object_search", "perception"},
               "render": {"solver", "object_search", "render"},
               "sim": {"solver", "object_search", "render", "sim"},
               "api": {"solver", "object_search", "render", "perception", "api"}}
    for d, module in homes.items():
        for path, inc in includes(d):
            if not inc.startswith("npfkct/"):
                continue
            used = inc.split("/")[1]
            used = {"object_search": "object_search", "filter": "filter", "sim": "sim",
                    "perception": "perception", "api": "api", "server": "server",
                    "solver": "solver", "render": "render"}.get(used, used)
            if used in order:
                assert used in allowed[module], f"{path} ({module}) includes {inc}"

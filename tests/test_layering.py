"""The layers, checked on the sources of every folder (the CMake configure step checks the links,
npfkct_layer in CMakeLists.txt): a folder is a layer, and a file includes the headers of its own
layer and of the layers below it only. Every folder with C++ sources must be a layer of the table,
so a new folder cannot escape the check. A module's tests (its test/ folder) may also take the
simulator and the filter's training data as fixtures; the library code never does.

    python3 -m pytest tests/test_layering.py
"""

import os
import re

from conftest import ROOT

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.M)

# The layers, lowest first: (folder, the module its headers are included as, npfkct/<module>/,
# the modules it may include besides its own). A layer may only use layers listed before it.
_BASE = ["common"]
_SOLVER = _BASE + ["solver"]
_MODEL = _SOLVER + ["object_search"]
LAYERS = [
    ("common", "common", []),
    ("solver", "solver", _BASE),
    ("object_search", "object_search", _SOLVER),
    ("render", "render", _MODEL),
    ("filter", "filter", _MODEL),
    ("perception", "perception", _MODEL),
    ("robot", "robot", _MODEL),
    ("server/api", "api", _MODEL + ["render", "perception", "robot"]),
    ("server", "server", _MODEL + ["render", "filter", "perception", "api"]),
    ("sim", "sim", _MODEL + ["render", "api"]),
    ("clients", "client", _MODEL + ["render", "perception", "api", "sim"]),
    ("tools", "train", _MODEL + ["render", "filter", "perception", "api", "sim"]),
    ("bench", "bench", _MODEL + ["render", "filter", "perception", "api", "sim"]),
    ("tests", "tests", _MODEL + ["render", "filter", "perception", "api", "server", "sim",
                                 "client", "train"]),
]
# What a module's tests may use besides what the module may: scenes, frames and training data.
TEST_FIXTURES = ["sim", "train"]
# Libraries only some layers may include (the solver is Eigen only; JSON is the API layer's and
# above; the network is the filter's; point clouds and images are perception's and above).
THIRD_PARTY = {
    "nlohmann/": {"server/api", "sim", "clients", "tools", "bench", "tests"},
    "httplib": {"server", "tests"},
    "torch/": {"filter", "tools", "bench", "tests"},
    "pcl/": {"perception", "server/api", "server", "sim", "clients", "tools", "bench", "tests"},
    "opencv2/": {"render", "perception", "server/api", "server", "sim", "clients", "tools",
                 "bench", "tests"},
    "urdf_": {"robot"},
    "kdl/": {"robot"},
}
SKIP = {".git", "build", "node_modules"}


def layer_of(path):
    """The layer entry of a repository-relative path (the deepest folder that is a layer)."""
    best = None
    for entry in LAYERS:
        folder = entry[0]
        if path == folder or path.startswith(folder + "/"):
            if best is None or len(folder) > len(best[0]):
                best = entry
    return best


def sources(root):
    """(relative path, text) of every C++ file under root."""
    for d, dirs, files in os.walk(root):
        dirs[:] = [x for x in dirs if x not in SKIP and not x.startswith("build")]
        for f in files:
            if f.endswith((".cc", ".h", ".hpp", ".cpp")):
                path = os.path.join(d, f)
                with open(path, encoding="utf-8") as fh:
                    yield os.path.relpath(path, root).replace(os.sep, "/"), fh.read()


def violations(root):
    """Every include that runs from a lower folder to a higher one, every third-party include a
    layer may not use, and every C++ file outside the table, as readable lines."""
    out = []
    module_rank = {m: i for i, (_, m, _) in enumerate(LAYERS)}
    for path, text in sources(root):
        entry = layer_of(path)
        if entry is None:
            out.append(f"{path}: its folder is not a layer of tests/test_layering.py")
            continue
        folder, own, allowed = entry
        allowed = set(allowed) | {own}
        if "/test/" in path:
            allowed |= set(TEST_FIXTURES)
        for inc in INCLUDE.findall(text):
            if inc.startswith("npfkct/"):
                used = inc.split("/")[1]
                if used in module_rank and used not in allowed:
                    out.append(f"{path} ({folder}) includes {inc}")
            for prefix, layers in THIRD_PARTY.items():
                if inc.startswith(prefix) and folder not in layers:
                    out.append(f"{path} ({folder}) includes {inc}")
    return out


def test_the_table_runs_one_way():
    seen = set()
    for folder, module, allowed in LAYERS:
        assert set(allowed) <= seen, f"{folder} may use a layer above it: {set(allowed) - seen}"
        seen.add(module)
    assert set(TEST_FIXTURES) <= seen


def test_no_include_runs_from_a_lower_folder_to_a_higher_one():
    bad = violations(ROOT)
    assert not bad, "\n".join(bad)


def test_every_folder_with_cpp_sources_is_a_layer():
    folders = {os.path.dirname(p) for p, _ in sources(ROOT)}
    assert {"common/src", "solver/src", "server/api/src", "sim/src", "bench/src",
            "clients/driver", "tools/train/src"} <= folders
    assert all(layer_of(f) is not None for f in folders), sorted(
        f for f in folders if layer_of(f) is None)


def test_a_planted_back_include_is_found(tmp_path):
    def plant(path, text):
        p = tmp_path / path
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)

    plant("solver/src/fine.cc", '#include "npfkct/common/status.h"\n#include <Eigen/Core>\n')
    plant("server/src/fine.cc", '#include "npfkct/api/api.h"\n#include <httplib.h>\n')
    plant("perception/test/fixture_test.cc", '#include "npfkct/sim/simulator.h"\n')
    assert violations(tmp_path) == []

    plant("object_search/src/up.cc", '#include "npfkct/server/session.h"\n')
    plant("server/api/src/up.cc", '#include "npfkct/sim/scenario.h"\n')
    plant("perception/src/fixture.cc", '#include "npfkct/sim/simulator.h"\n')
    plant("solver/include/npfkct/solver/json.h", "#include <nlohmann/json.hpp>\n")
    plant("server/src/wire.cc", "#  include <nlohmann/json.hpp>\n")
    plant("newfolder/x.cc", "int x;\n")
    bad = violations(tmp_path)
    assert len(bad) == 6, bad
    for needle in ("object_search/src/up.cc (object_search) includes npfkct/server/",
                   "server/api/src/up.cc (server/api) includes npfkct/sim/",
                   "perception/src/fixture.cc (perception) includes npfkct/sim/",
                   "solver/include/npfkct/solver/json.h (solver) includes nlohmann/",
                   "server/src/wire.cc (server) includes nlohmann/",
                   "newfolder/x.cc: its folder is not a layer"):
        assert any(needle in b for b in bad), (needle, bad)


def test_wire_formats_are_implemented_in_the_api_layer_only():
    # Image codecs and Base64 are the API layer's; the layers above call its encoders.
    codec = re.compile(r"cv::imdecode|cv::imencode|ABCDEFGHIJKLMNOPQRSTUVWXYZabcdef")
    bad = [p for p, text in sources(ROOT)
           if codec.search(text) and layer_of(p)[0] not in ("server/api", "tests")
           and "/test/" not in p]
    assert not bad, bad

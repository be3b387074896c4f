"""The Docker images (docker/Dockerfile, deploy/Dockerfile.replica) read as files, since no Docker
engine runs here: two stages, bases pinned to a Debian point release, the dependency layer before
`COPY . .`, and a runtime stage that installs only libraries (no compiler, -dev package, ROS or
test tool) yet every library the built server links. docker/compose.yaml refuses to start
without NPFKCT_AUTH (deploy/compose.yaml: tests/test_deploy.py)."""

import os
import re
import shutil
import subprocess

import pytest
import yaml

from conftest import ROOT, SERVER_BIN

DOCKERFILES = {
    "docker/Dockerfile": {"store": False},
    "deploy/Dockerfile.replica": {"store": True},
}
# Packages a runtime image must not hold, by name: compilers and build tools, headers, ROS, tests.
FORBIDDEN = re.compile(r"^(build-essential|gcc(-\d+)?|g\+\+(-\d+)?|cpp(-\d+)?|clang.*|llvm.*|"
                       r"cmake.*|make|ninja-build|ccache|binutils.*|libc6-dev|.*-dev|ros-.*|"
                       r"python3-ros.*|catkin|python3-pytest|python3-pip|gdb|valgrind)$")
# What every Debian image has: the server's links to these need no package of ours.
BASE = {"libc6", "libgcc-s1", "libstdc++6", "zlib1g"}


def instructions(path):
    """[(stage, INSTRUCTION, arguments)] of a Dockerfile: comments dropped, continuations joined;
    stage is the name after FROM ... AS (or its index)."""
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        text = f.read()
    text = re.sub(r"(?m)^\s*#.*\n", "", text)
    text = re.sub(r"\\\n", " ", text)
    out, stage = [], None
    for line in text.splitlines():
        if not line.strip():
            continue
        word, _, args = line.strip().partition(" ")
        word = word.upper()
        if word == "FROM":
            m = re.match(r"(\S+)(?:\s+AS\s+(\S+))?$", args.strip(), re.I)
            stage = m.group(2) or str(sum(1 for i in out if i[1] == "FROM"))
        out.append((stage, word, " ".join(args.split())))
    return out


def stage(path, name):
    return [(w, a) for s, w, a in instructions(path) if s == name]


def deps_array(name):
    out = subprocess.run(["bash", "-c", f'source scripts/deps.sh && echo "${{{name}[@]}}"'],
                         cwd=ROOT, capture_output=True, text=True, check=True, timeout=30)
    return out.stdout.split()


def installed_packages(run_args):
    """The packages a RUN instruction installs: the deps.sh arrays it names, and the arguments of
    apt-get install."""
    packages = []
    for array in re.findall(r"\$\{(NPFKCT_[A-Z_]+)\[@\]\}", run_args):
        packages += deps_array(array)
    for m in re.finditer(r"apt-get install ([^&;|]*)", run_args):
        packages += [p for p in m.group(1).split() if not p.startswith("-")]
    return packages


def closure(packages):
    """The packages `packages` bring in (their Depends and PreDepends, recursively)."""
    out = subprocess.run(["apt-cache", "depends", "--recurse", "--no-recommends", "--no-suggests",
                          "--no-conflicts", "--no-breaks", "--no-replaces", "--no-enhances",
                          *packages], capture_output=True, text=True, check=True, timeout=300)
    return {line.strip() for line in out.stdout.splitlines()
            if line and not line.startswith(" ") and not line.startswith("<")}


def package_of(library):
    """The Debian package that holds `library` (by its path, or the file it links to; with or
    without /usr, which Debian 12 merges)."""
    real = os.path.realpath(library)
    for path in (library, real):
        for candidate in (path, re.sub(r"^/usr/", "/", path), re.sub(r"^/lib", "/usr/lib", path)):
            out = subprocess.run(["dpkg", "-S", candidate], capture_output=True, text=True)
            if out.returncode == 0:
                return out.stdout.split(":")[0]
    return None


@pytest.mark.parametrize("path", sorted(DOCKERFILES))
def test_two_stages_on_a_pinned_base(path):
    froms = [a for _, w, a in instructions(path) if w == "FROM"]
    assert [f.split()[-1] for f in froms] == ["build", "runtime"], froms
    for f in froms:
        image = f.split()[0]
        # A Debian point release (12.8), optionally with its digest; never latest or bookworm.
        assert re.fullmatch(r"debian:12\.\d+(-slim)?(@sha256:[0-9a-f]{64})?", image), image


@pytest.mark.parametrize("path", sorted(DOCKERFILES))
def test_the_dependency_layer_comes_before_the_sources(path):
    build = stage(path, "build")
    copy_all = next(i for i, (w, a) in enumerate(build) if w == "COPY" and a.split()[0] == ".")
    install = next(i for i, (w, a) in enumerate(build)
                   if w == "RUN" and installed_packages(a))
    assert install < copy_all
    for w, a in build[:install]:  # nothing but the package lists reaches that layer
        assert w != "COPY" or a.split()[0] == "scripts/deps.sh", a
    assert "NPFKCT_BUILD_PACKAGES" in build[install][1]


@pytest.mark.parametrize("path", sorted(DOCKERFILES))
def test_the_runtime_stage_has_no_build_tools(path):
    runtime = stage(path, "runtime")
    for w, a in runtime:
        if w == "COPY":
            assert a.startswith("--from=build ") or a.split()[0] == "scripts/deps.sh", a
        if w == "RUN":
            assert not re.search(r"\b(cmake|make|gcc|g\+\+|clang|pip|npm)\b", a), a
    packages = [p for w, a in runtime if w == "RUN" for p in installed_packages(a)]
    assert packages
    assert [p for p in packages if FORBIDDEN.match(p)] == []
    entry = next(a for w, a in runtime if w == "ENTRYPOINT")
    binary = re.match(r'\["([^"]+)"', entry).group(1)
    assert any(w == "COPY" and a.startswith("--from=build ") and a.endswith(" " + binary)
               for w, a in runtime), binary


@pytest.mark.parametrize("path", sorted(DOCKERFILES))
def test_the_runtime_packages_bring_no_compiler_and_every_linked_library(path):
    """Through Debian's dependencies (apt-cache): no runtime library drags a compiler in, and
    every library the server built here links comes with the runtime packages."""
    if not shutil.which("apt-cache") or not shutil.which("readelf"):
        pytest.skip("apt-cache and readelf are needed (Debian's apt and binutils)")
    runtime = stage(path, "runtime")
    packages = [p for w, a in runtime if w == "RUN" for p in installed_packages(a)]
    if subprocess.run(["apt-cache", "show", packages[0]], capture_output=True).returncode != 0:
        pytest.skip("apt's package lists are empty here (apt-get update fills them)")
    brought = closure(packages)
    assert [p for p in brought if FORBIDDEN.match(p)] == []
    needed = re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]",
                        subprocess.run(["readelf", "-d", SERVER_BIN], capture_output=True,
                                       text=True, check=True).stdout)
    ldd = subprocess.run(["ldd", SERVER_BIN], capture_output=True, text=True, check=True).stdout
    missing = []
    for lib in needed:
        if lib.startswith("ld-linux"):
            continue  # the dynamic loader itself (libc6; ldd lists it without "=>")
        m = re.search(rf"^\s*{re.escape(lib)} => (\S+)", ldd, re.M)
        assert m, lib
        owner = package_of(m.group(1))
        if owner == "libpq5" and not DOCKERFILES[path]["store"]:
            continue  # this build has the PostgreSQL store; docker/Dockerfile's has not
        if owner not in brought and owner not in BASE:
            missing.append((lib, owner))
    assert missing == []


def test_compose_refuses_to_start_without_auth():
    if not shutil.which("docker-compose"):
        pytest.fail("docker-compose is not installed (scripts/deps.sh installs it)")
    compose = os.path.join(ROOT, "docker", "compose.yaml")

    def config(**env):
        environ = {k: v for k, v in os.environ.items() if k != "NPFKCT_AUTH"}
        return subprocess.run(["docker-compose", "-f", compose, "config"], capture_output=True,
                              text=True, env=dict(environ, **env), timeout=60)

    for env in ({}, {"NPFKCT_AUTH": ""}):
        out = config(**env)
        assert out.returncode != 0 and "NPFKCT_AUTH" in out.stderr, out.stderr
        assert "--insecure" in out.stderr
    for auth in ("--api-key=k3y", "--insecure"):
        out = config(NPFKCT_AUTH=auth)
        assert out.returncode == 0, out.stderr
        assert yaml.safe_load(out.stdout)["services"]["npfkct"]["command"][-1] == auth

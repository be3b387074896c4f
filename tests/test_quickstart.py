"""A new user's first steps, from the README: `cmake --install` into a fresh prefix, the README's
quick start block run as written (in bash, as if pasted; only its port is replaced by a free one),
the installed programs' --help, and a CMake project that embeds the installed package through
find_package(npfkct) (tests/consumer)."""

import json
import os
import re
import subprocess

import pytest

from conftest import BUILD, ROOT, ServerProcess, free_port


def readme_block():
    """The fenced block after the README's `<!-- quickstart -->` marker."""
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        text = f.read()
    m = re.search(r"<!-- quickstart -->\n```sh\n(.*?)\n```", text, re.S)
    assert m, "README.md has no quick start block"
    return m.group(1)


@pytest.fixture(scope="module")
def home(tmp_path_factory):
    """A fresh HOME whose ~/.local receives the install, and a working directory whose `build`
    is this build directory (the README runs from the repository's root)."""
    home = tmp_path_factory.mktemp("home")
    work = home / "repo"
    work.mkdir()
    os.symlink(BUILD, work / "build")
    return home


def test_the_readme_quick_start_runs_as_written(home):
    block = readme_block()
    assert "8080" in block
    port = free_port()
    script = block.replace("8080", str(port))
    env = {**os.environ, "HOME": str(home)}
    out = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=home / "repo",
                         env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    lines = [json.loads(l) for l in out.stdout.splitlines() if l.startswith("{")]
    planned, observed = lines[0], lines[1]
    assert planned["action"]["type"] in ("MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE")
    # The session asked for npfkct without naming a model: it planned with the shipped one.
    assert planned["model"] == "filter.pt"
    assert set(observed) == {"reward", "done"} and observed["done"] is False
    with open(home / "repo" / "belief.png", "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"


def test_installed_programs_answer_help(home):
    bin_dir = home / ".local" / "bin"
    if not (bin_dir / "npfkct-server").exists():
        subprocess.run(["cmake", "--install", BUILD, "--prefix", str(home / ".local")],
                       check=True, capture_output=True)
    for program in ("npfkct-server", "npfkct-drive", "npfkct-bench", "npfkct-train",
                    "npfkct-sim-robot", "npfkct-client"):
        out = subprocess.run([str(bin_dir / program), "--help"], capture_output=True, text=True,
                             timeout=60)
        assert out.returncode == 0, (program, out.stderr)
        assert "usage" in (out.stdout + out.stderr).lower(), program


def test_a_project_embeds_the_installed_package(home, tmp_path):
    prefix = home / ".local"
    if not (prefix / "lib" / "cmake" / "npfkct" / "npfkctConfig.cmake").exists():
        subprocess.run(["cmake", "--install", BUILD, "--prefix", str(prefix)], check=True,
                       capture_output=True)
    build = tmp_path / "consumer"
    configure = subprocess.run(
        ["cmake", "-S", os.path.join(ROOT, "tests", "consumer"), "-B", str(build),
         f"-DCMAKE_PREFIX_PATH={prefix}", "-DCMAKE_BUILD_TYPE=Release"],
        capture_output=True, text=True, timeout=300)
    assert configure.returncode == 0, configure.stdout[-2000:] + configure.stderr[-2000:]
    made = subprocess.run(["cmake", "--build", str(build), "-j2"], capture_output=True,
                          text=True, timeout=900)
    assert made.returncode == 0, made.stdout[-3000:] + made.stderr[-3000:]
    # The installed server, found through its install layout (its default model folder is the
    # installed share/npfkct/models).
    server = ServerProcess(binary=str(prefix / "bin" / "npfkct-server"))
    try:
        out = subprocess.run([str(build / "consumer"), server.url], capture_output=True,
                             text=True, timeout=120)
    finally:
        server.stop()
    assert out.returncode == 0, out.stderr
    assert "solver: tiger listens first" in out.stdout
    assert "client: server SERVING" in out.stdout
    assert "plans with model 'filter.pt'" in out.stdout
    assert "client: planned " in out.stdout

"""The Debian packages (cmake/npfkct_package.cmake, `cpack -G DEB`, and npfkct-ros by
clients/ros/npfkct_ros/build_deb.sh): what each holds and needs, and the packages installed with
apt on a fresh Debian 12 root (mmdebstrap from Debian's mirror, the minbase variant) where the
README's quick start runs from them (the installed server, client, simulated robot and
scenarios, no build tree) and the ROS node's modules import. Needs mmdebstrap and dpkg-dev
(scripts/deps.sh) and Debian's mirror; runs as root (mmdebstrap's root mode)."""

import glob
import json
import os
import re
import shutil
import subprocess

import pytest

from conftest import BUILD, ROOT, free_port

PACKAGES = os.path.join(BUILD, "packages")
NAMES = ("npfkct-server", "libnpfkct-dev", "python3-npfkct-client")
ROS_PACKAGE = os.path.join(ROOT, "clients", "ros", "npfkct_ros")


@pytest.fixture(scope="module")
def debs():
    """{package name: .deb path}, built by cpack from this build's install rules."""
    for tool in ("cpack", "dpkg-deb", "dpkg-shlibdeps"):
        if not shutil.which(tool):
            pytest.fail(f"{tool} is not installed (scripts/deps.sh installs cmake and dpkg-dev)")
    for old in glob.glob(os.path.join(PACKAGES, "*.deb")):
        os.remove(old)
    out = subprocess.run(["cpack", "-G", "DEB", "--config", os.path.join(BUILD, "CPackConfig.cmake")],
                         cwd=BUILD, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    found = {}
    for path in glob.glob(os.path.join(PACKAGES, "*.deb")):
        name = os.path.basename(path).split("_")[0]
        found[name] = path
    assert set(found) == set(NAMES), found
    return found


@pytest.fixture(scope="module")
def ros_deb(tmp_path_factory):
    """npfkct-ros, packed by clients/ros/npfkct_ros/build_deb.sh from a fresh catkin workspace."""
    if not shutil.which("catkin_make"):
        pytest.fail("catkin is not installed (scripts/deps.sh installs it)")
    ws = tmp_path_factory.mktemp("ros-ws")
    (ws / "src").mkdir()
    os.symlink(ROS_PACKAGE, ws / "src" / "npfkct_ros")
    # Not into PACKAGES, which the cpack fixture empties of .deb files first.
    out = subprocess.run([os.path.join(ROS_PACKAGE, "build_deb.sh"), str(ws), str(ws / "out")],
                         capture_output=True, text=True, timeout=1200)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return out.stdout.strip().splitlines()[-1]


def test_the_ros_package_is_a_debian_package_of_its_own(ros_deb):
    assert field(ros_deb, "Package") == "npfkct-ros" and field(ros_deb, "Architecture") == "all"
    depends = field(ros_deb, "Depends")
    for need in ("python3-npfkct-client", "python3-rospy", "python3-actionlib",
                 "python3-visualization-msgs"):
        assert need in depends, depends
    files = contents(ros_deb)
    for path in ("/usr/lib/npfkct_ros/npfkct_node", "/usr/share/npfkct_ros/launch/npfkct.launch",
                 "/usr/share/npfkct_ros/package.xml",
                 "/usr/lib/python3/dist-packages/npfkct_ros/find_object.py",
                 "/usr/lib/python3/dist-packages/npfkct_ros/msg/_FindObjectAction.py"):
        assert path in files, path
    # The client comes from python3-npfkct-client, not a second copy; no workspace files.
    assert not any("npfkct_client" in p for p in files)
    assert not any(p.endswith(("setup.bash", "_setup_util.py", ".catkin")) for p in files)


def field(deb, name):
    return subprocess.run(["dpkg-deb", "-f", deb, name], capture_output=True, text=True,
                          check=True).stdout.strip()


def contents(deb):
    listing = subprocess.run(["dpkg-deb", "-c", deb], capture_output=True, text=True,
                             check=True).stdout
    return {line.split()[-1].lstrip(".") for line in listing.splitlines()}


def test_each_package_holds_its_part_and_names_what_it_needs(debs):
    version = re.search(r"project\(npfkct VERSION ([0-9.]+)",
                        open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8").read())[1]
    for name, deb in debs.items():
        assert field(deb, "Package") == name and field(deb, "Version") == version + "-1"
        assert f"/usr/share/doc/{name}/copyright" in contents(deb)
    server = contents(debs["npfkct-server"])
    for path in ("/usr/bin/npfkct-server", "/usr/bin/npfkct-drive", "/usr/bin/npfkct-sim-robot",
                 "/usr/share/npfkct/models/filter.pt", "/usr/share/npfkct/scenarios/loose1.json",
                 "/lib/systemd/system/npfkct-server.service", "/etc/default/npfkct-server"):
        assert path in server, path
    # Its runtime libraries come from dpkg-shlibdeps, with no -dev package among them.
    depends = field(debs["npfkct-server"], "Depends")
    for lib in ("libtorch1.13", "libpcl-common1.13", "libopencv-core406", "liburdfdom-model3.0"):
        assert lib in depends, depends
    assert "-dev" not in depends, depends
    dev = contents(debs["libnpfkct-dev"])
    assert "/usr/lib/cmake/npfkct/npfkctConfig.cmake" in dev
    assert "/usr/include/npfkct/solver/kct.h" in dev and "/usr/bin/npfkct-bench" in dev
    assert not any(p.startswith("/usr/bin/npfkct-server") for p in dev)
    client = contents(debs["python3-npfkct-client"])
    assert "/usr/bin/npfkct-client" in client
    assert "/usr/share/npfkct/python/npfkct_client/client.py" in client
    assert not any("__pycache__" in p for p in client)
    assert field(debs["python3-npfkct-client"], "Architecture") == "all"
    assert "python3-requests" in field(debs["python3-npfkct-client"], "Depends")
    # The conffile: a changed /etc/default/npfkct-server survives an upgrade.
    control = subprocess.run(["dpkg-deb", "-I", debs["npfkct-server"], "conffiles"],
                             capture_output=True, text=True, check=True).stdout
    assert control.split() == ["/etc/default/npfkct-server"]


def unit_problems(path):
    """systemd-analyze's complaints about a unit file, but that its program is not installed
    here."""
    out = subprocess.run(["systemd-analyze", "verify", "--man=no", str(path)],
                         capture_output=True, text=True, timeout=60)
    return [line for line in (out.stdout + out.stderr).splitlines()
            if "npfkct-server.service" in line and "/usr/bin/npfkct-server" not in line]


def test_the_systemd_unit_is_valid(tmp_path):
    unit = os.path.join(ROOT, "deploy", "debian", "npfkct-server.service")
    if not shutil.which("systemd-analyze"):
        pytest.skip("systemd-analyze is not installed")
    text = open(unit, encoding="utf-8").read()
    assert "StateDirectory=npfkct" in text and "DynamicUser=yes" in text
    assert "--state-dir /var/lib/npfkct" in text
    assert unit_problems(unit) == []
    # Not vacuous: a setting systemd cannot read is reported.
    broken = tmp_path / "npfkct-server.service"
    broken.write_text(text.replace("DynamicUser=yes", "DynamicUser=perhaps"))
    assert unit_problems(broken), "systemd-analyze found nothing wrong with a broken unit"


def readme_quick_start():
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        block = re.search(r"<!-- quickstart -->\n```sh\n(.*?)\n```", f.read(), re.S)[1]
    lines = block.splitlines()
    # From the packages: no cmake --install, no PATH of its own, the data under /usr/share.
    assert lines[0].startswith("cmake --install") and lines[1].startswith("export PATH=")
    return "\n".join(lines[2:]).replace('"$HOME/.local/share/', '"/usr/share/')


def test_the_packages_install_on_a_fresh_debian_12_root_and_run_the_quick_start(debs, ros_deb,
                                                                                 tmp_path):
    """mmdebstrap builds a minimal Debian 12 root with curl and jq and installs the server and
    client packages with apt (their dependencies from the mirror); inside it, the README's quick
    start runs from the installed programs and data. The root's size is recorded in
    BUILD/packages/root.json (what an image of these packages holds)."""
    if not shutil.which("mmdebstrap"):
        pytest.fail("mmdebstrap is not installed (scripts/deps.sh installs it)")
    if os.geteuid() != 0:
        pytest.skip("mmdebstrap's root mode needs root")
    port = free_port()
    script = tmp_path / "quickstart.sh"
    script.write_text(readme_quick_start().replace("8080", str(port)) + "\n")
    root = tmp_path / "root"
    # As a user would: the .deb files in a folder of the new root, installed with apt (which
    # fetches their dependencies from the mirror), then the quick start.
    server, client = (os.path.basename(debs[n]) for n in ("npfkct-server", "python3-npfkct-client"))
    ros = os.path.basename(ros_deb)
    hooks = [
        f'mkdir "$1/srv/qs" && cp {debs["npfkct-server"]} {debs["python3-npfkct-client"]} '
        f'{ros_deb} {script} "$1/srv/qs/"',
        f'chroot "$1" sh -c "cd /srv/qs && apt-get install -y ./{server} ./{client} ./{ros}"',
        'chroot "$1" timeout 600 /bin/bash -e -o pipefail -c '
        '"cd /srv/qs && bash -e -o pipefail quickstart.sh > quickstart.out 2>&1"',
    ]
    out = subprocess.run(
        ["mmdebstrap", "--variant=minbase", "--include=curl,jq,ca-certificates",
         "--aptopt=Acquire::Retries \"3\"",
         "--dpkgopt=path-exclude=/usr/share/doc/*",
         "--dpkgopt=path-include=/usr/share/doc/*/copyright",
         "--dpkgopt=path-exclude=/usr/share/man/*", "--dpkgopt=path-exclude=/usr/share/locale/*",
         *(f"--customize-hook={h}" for h in hooks), "bookworm", str(root),
         "http://deb.debian.org/debian"],
        capture_output=True, text=True, timeout=1800)
    ran = root / "srv" / "qs" / "quickstart.out"
    log = ran.read_text(errors="replace")[-3000:] if ran.exists() else "(no output)"
    assert out.returncode == 0, out.stderr[-3000:] + "\nquick start:\n" + log
    lines = [json.loads(line) for line in ran.read_text().splitlines() if line.startswith("{")]
    planned, observed = lines[0], lines[1]
    assert planned["action"]["type"] in ("MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE")
    assert planned["model"] == "filter.pt"  # the packaged model, found beside /usr/bin
    assert set(observed) == {"reward", "done"} and observed["done"] is False
    assert (root / "srv" / "qs" / "belief.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The installed client is Debian's python3's, and the ROS node's modules and messages load
    # with it.
    imported = subprocess.run(["chroot", str(root), "python3", "-c",
                               "import npfkct_client; import npfkct_ros.find_object; "
                               "from npfkct_ros.msg import FindObjectAction; "
                               "print(npfkct_client.__version__)"],
                              capture_output=True, text=True, timeout=60)
    assert imported.returncode == 0 and imported.stdout.strip(), imported.stderr
    size = int(subprocess.run(["du", "-sxb", str(root)], capture_output=True, text=True,
                              check=True).stdout.split()[0])
    count = len(subprocess.run(["chroot", str(root), "dpkg-query", "-W"], capture_output=True,
                               text=True, check=True).stdout.splitlines())
    with open(os.path.join(PACKAGES, "root.json"), "w", encoding="utf-8") as f:
        json.dump({"bytes": size, "packages": count}, f)
    print(f"root with npfkct-server and python3-npfkct-client: {size / 2**20:.0f} MiB, "
          f"{count} packages")

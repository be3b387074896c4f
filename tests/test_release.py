"""One license and one version everywhere: LICENSE at the root, the same license in every
package's metadata, and the version of CMakeLists.txt's project() in the Python client, the ROS
package, the OpenAPI document, the CHANGELOG, every program's --version and GET /healthz."""

import json
import os
import re
import subprocess
import urllib.request
import xml.etree.ElementTree as ET

import yaml

from conftest import BUILD, ROOT, ServerProcess

PROGRAMS = ["npfkct-server", "npfkct-sim-robot", "npfkct-drive", "npfkct-bench",
            "npfkct-perception-bench", "npfkct-train"]


def read(*parts):
    with open(os.path.join(ROOT, *parts), encoding="utf-8") as f:
        return f.read()


def project_version():
    m = re.search(r"project\(npfkct VERSION (\d+\.\d+\.\d+)", read("CMakeLists.txt"))
    assert m, "CMakeLists.txt's project() names no version"
    return m.group(1)


def test_the_license_is_apache_2_everywhere():
    text = read("LICENSE")
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    assert re.search(r'license = \{text = "Apache-2.0"\}', read("clients", "python",
                                                                "pyproject.toml"))
    package = ET.fromstring(read("clients", "ros", "npfkct_ros", "package.xml"))
    assert [e.text for e in package.findall("license")] == ["Apache-2.0"]
    info = yaml.safe_load(read("schemas", "openapi.yaml"))["info"]
    assert info["license"]["identifier"] == "Apache-2.0"
    assert "Apache License 2.0" in read("README.md")


def test_every_place_names_the_project_version():
    version = project_version()
    init = read("clients", "python", "npfkct_client", "__init__.py")
    assert re.search(r'__version__ = "([^"]+)"', init).group(1) == version
    package = ET.fromstring(read("clients", "ros", "npfkct_ros", "package.xml"))
    assert package.find("version").text == version
    assert yaml.safe_load(read("schemas", "openapi.yaml"))["info"]["version"] == version
    # The newest release in the CHANGELOG is this one.
    releases = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", read("CHANGELOG.md"), re.M)
    assert releases and releases[0] == version
    with open(os.path.join(BUILD, "npfkctConfigVersion.cmake"), encoding="utf-8") as f:
        assert f'set(PACKAGE_VERSION "{version}")' in f.read()


def test_every_program_prints_the_version():
    version = project_version()
    for program in PROGRAMS:
        out = subprocess.run([os.path.join(BUILD, "bin", program), "--version"], check=True,
                             capture_output=True, text=True, timeout=60).stdout
        assert out.strip() == f"{program} {version}", program


def test_healthz_reports_the_version():
    server = ServerProcess()
    try:
        with urllib.request.urlopen(server.url + "/healthz", timeout=10) as reply:
            health = json.load(reply)
        assert health["status"] == "SERVING"
        assert health["version"] == project_version()
    finally:
        assert server.stop() == 0

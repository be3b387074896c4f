"""deploy/: the Kubernetes manifests validated against Kubernetes' OpenAPI schemas
(kubernetes-models from npm, run by Node.js), the compose file checked by docker-compose, the
router's nginx configuration in Kubernetes kept equal to deploy/nginx/npfkct.conf, and every
server flag the files pass known to npfkct-server."""

import glob
import json
import os
import re
import shutil
import subprocess

import pytest
import yaml

from conftest import ROOT, SERVER_BIN, npm_tool

DEPLOY = os.path.join(ROOT, "deploy")
K8S_TOOL = os.path.join(ROOT, "tests", "k8s")


def manifests():
    objects = []
    for path in sorted(glob.glob(os.path.join(DEPLOY, "k8s", "*.yaml"))):
        with open(path, encoding="utf-8") as f:
            objects += [o for o in yaml.safe_load_all(f) if o]
    return objects


@pytest.fixture(scope="module")
def validator():
    """validate.mjs with its node_modules (npm ci into the build directory once per lock
    file)."""
    work = npm_tool(K8S_TOOL, "k8s-validate")

    def validate(objects):
        out = subprocess.run(["node", os.path.join(work, "validate.mjs")],
                             input=json.dumps(objects), capture_output=True, text=True,
                             check=True, timeout=120)
        return json.loads(out.stdout)

    return validate


def test_kubernetes_manifests_are_valid(validator):
    objects = manifests()
    kinds = sorted(o["kind"] for o in objects)
    assert kinds == ["ConfigMap", "Deployment", "Deployment", "Namespace", "PodDisruptionBudget",
                     "Secret", "Secret", "Service", "Service"]
    results = validator(objects)
    assert [r for r in results if r["error"]] == []
    assert len(results) == len(objects)


def test_the_validator_refuses_a_broken_manifest(validator):
    deployment = next(o for o in manifests() if o["kind"] == "Deployment")
    broken = json.loads(json.dumps(deployment))
    broken["spec"]["replicas"] = "three"
    missing = json.loads(json.dumps(deployment))
    del missing["spec"]["selector"]
    results = validator([broken, missing])
    assert "replicas" in results[0]["error"]
    assert "selector" in results[1]["error"]


def test_manifests_fit_together():
    objects = manifests()
    by = {(o["kind"], o["metadata"]["name"]): o for o in objects}
    assert all(o["metadata"].get("namespace", "npfkct") == "npfkct" for o in objects)
    replicas = by[("Deployment", "npfkct")]
    labels = replicas["spec"]["template"]["metadata"]["labels"]
    assert by[("Service", "npfkct-replicas")]["spec"]["selector"].items() <= labels.items()
    assert by[("Service", "npfkct-replicas")]["spec"]["clusterIP"] == "None"  # one record each
    router = by[("Deployment", "npfkct-router")]
    assert by[("Service", "npfkct")]["spec"]["selector"].items() <= \
        router["spec"]["template"]["metadata"]["labels"].items()
    env = replicas["spec"]["template"]["spec"]["containers"][0]["env"]
    secret_ref = next(e for e in env if e["name"] == "NPFKCT_STORE")["valueFrom"]["secretKeyRef"]
    assert secret_ref["name"] == "npfkct-store"
    assert secret_ref["key"] in by[("Secret", "npfkct-store")]["stringData"]
    # The replicas listen on 0.0.0.0: without a key they would refuse to start.
    key_ref = next(e for e in env if e["name"] == "NPFKCT_API_KEY")["valueFrom"]["secretKeyRef"]
    assert key_ref["key"] in by[("Secret", key_ref["name"])]["stringData"]
    assert router["spec"]["template"]["spec"]["volumes"][0]["configMap"]["name"] == "npfkct-nginx"


def _routing(conf):
    """The routing of an npfkct.conf without its comments and upstream servers (which differ
    between compose and Kubernetes)."""
    lines = []
    for line in conf.splitlines():
        line = line.split("#", 1)[0].strip() if not line.strip().startswith('"') else line.strip()
        if not line or line.startswith("server ") or line.startswith("zone "):
            continue
        lines.append(line)
    return lines


def test_kubernetes_router_routes_like_the_compose_one():
    with open(os.path.join(DEPLOY, "nginx", "npfkct.conf"), encoding="utf-8") as f:
        compose_conf = f.read()
    config_map = next(o for o in manifests() if o["kind"] == "ConfigMap")
    k8s_conf = config_map["data"]["npfkct.conf"]
    assert _routing(k8s_conf) == _routing(compose_conf)
    assert "hash $npfkct_route_key consistent;" in k8s_conf
    assert "include /etc/nginx/npfkct/npfkct.conf;" in config_map["data"]["nginx.conf"]


def test_compose_file_is_valid():
    if not shutil.which("docker-compose"):
        pytest.fail("docker-compose is not installed (scripts/deps.sh installs it)")
    base = {k: v for k, v in os.environ.items() if k not in ("NPFKCT_DB_PASSWORD", "NPFKCT_AUTH")}

    def config(**env):
        return subprocess.run(["docker-compose", "-f", os.path.join(DEPLOY, "compose.yaml"),
                               "config"], capture_output=True, text=True, env=dict(base, **env),
                              timeout=60)

    out = config(NPFKCT_DB_PASSWORD="test-password", NPFKCT_AUTH="--api-key=test-key")
    assert out.returncode == 0, out.stderr
    rendered = yaml.safe_load(out.stdout)
    assert sorted(rendered["services"]) == ["nginx", "postgres", "replica1", "replica2", "replica3"]
    for name in ("replica1", "replica2", "replica3"):
        assert rendered["services"][name]["environment"]["NPFKCT_STORE"].startswith(
            "postgresql://npfkct:test-password@postgres:5432/")
        assert rendered["services"][name]["command"][-1] == "--api-key=test-key"
    # Without a password the file refuses to start rather than run a database without one.
    out = config(NPFKCT_AUTH="--api-key=test-key")
    assert out.returncode != 0 and "NPFKCT_DB_PASSWORD" in out.stderr
    # Without NPFKCT_AUTH (or with it empty) it refuses to start rather than serve the API on
    # 0.0.0.0 to anyone; --insecure must be asked for.
    for auth in ({}, {"NPFKCT_AUTH": ""}):
        out = config(NPFKCT_DB_PASSWORD="test-password", **auth)
        assert out.returncode != 0 and "NPFKCT_AUTH" in out.stderr and "--insecure" in out.stderr
    out = config(NPFKCT_DB_PASSWORD="test-password", NPFKCT_AUTH="--insecure")
    assert out.returncode == 0, out.stderr
    assert yaml.safe_load(out.stdout)["services"]["replica1"]["command"][-1] == "--insecure"


def test_compose_upstreams_are_the_compose_replicas():
    with open(os.path.join(DEPLOY, "nginx", "npfkct.conf"), encoding="utf-8") as f:
        upstreams = re.findall(r"(?m)^\s*server (\w+):8080 ", f.read())
    with open(os.path.join(DEPLOY, "compose.yaml"), encoding="utf-8") as f:
        services = yaml.safe_load(f)["services"]
    assert upstreams == ["replica1", "replica2", "replica3"]
    assert all(u in services for u in upstreams)


def test_every_flag_in_deploy_is_a_server_flag():
    helptext = subprocess.run([SERVER_BIN, "--help"], capture_output=True, text=True,
                              timeout=30).stdout
    known = set(re.findall(r"(--[a-z][a-z0-9-]*)", helptext))
    used = set()
    with open(os.path.join(DEPLOY, "compose.yaml"), encoding="utf-8") as f:
        used |= set(re.findall(r'"(--[a-z][a-z0-9-]*)"', f.read()))
    for o in manifests():
        if o["kind"] == "Deployment" and o["metadata"]["name"] == "npfkct":
            used |= {a for a in o["spec"]["template"]["spec"]["containers"][0]["args"]
                     if a.startswith("--")}
    with open(os.path.join(DEPLOY, "Dockerfile.replica"), encoding="utf-8") as f:
        used |= set(re.findall(r'"(--[a-z][a-z0-9-]*)"', f.read()))
    with open(os.path.join(DEPLOY, "compose.yaml"), encoding="utf-8") as f:
        used |= set(re.findall(r"NPFKCT_AUTH=(--[a-z][a-z0-9-]*)", f.read()))
    assert used and used <= known, used - known
    # The store URL comes from the environment in both (never in a file, which holds a password).
    assert "NPFKCT_STORE" in helptext

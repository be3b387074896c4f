"""Authentication: npfkct-server does not open its API to the network without a key unless told
--insecure; with --api-key (or NPFKCT_API_KEY) /v1 needs the bearer token and health and metrics
do not."""

import os
import subprocess

import requests

from conftest import SERVER_BIN, ServerProcess, world_of


def refused(*args, env=None):
    out = subprocess.run([SERVER_BIN, "--port", "0", "--log-level", "warn", *args],
                         capture_output=True, text=True, timeout=30, env=env)
    assert out.returncode != 0, out.stdout
    return out.stderr


def test_a_network_address_without_a_key_is_refused_naming_the_flags():
    for host in ("0.0.0.0", "::"):
        message = refused("--host", host)
        assert "api-key" in message and "--insecure" in message, message
        assert host in message, message
    # An empty key is no key (docker-compose passes "" for an unset variable).
    env = dict(os.environ, NPFKCT_API_KEY="")
    assert "--api-key" in refused("--host", "0.0.0.0", env=env)
    assert "--api-key" in refused("--host", "0.0.0.0", "--api-key", "")


def test_insecure_serves_a_network_address_without_a_key():
    s = ServerProcess("--host", "0.0.0.0", "--insecure")
    try:
        assert requests.get(s.url + "/v1/sessions", timeout=10).status_code == 200
    finally:
        assert s.stop() == 0


def check_key_is_required(s, key):
    url = s.url
    assert requests.get(url + "/v1/sessions", timeout=10).status_code == 401
    wrong = {"Authorization": "Bearer not-" + key}
    assert requests.get(url + "/v1/sessions", headers=wrong, timeout=10).status_code == 401
    good = {"Authorization": "Bearer " + key}
    created = requests.post(url + "/v1/sessions", headers=good, timeout=30,
                            json={"world": world_of("hidden1"), "seed": 1})
    assert created.status_code == 200, created.text
    assert requests.get(url + "/healthz", timeout=10).status_code == 200
    assert requests.get(url + "/metrics", timeout=10).status_code == 200


def test_a_network_address_with_a_key_requires_it():
    s = ServerProcess("--host", "0.0.0.0", "--api-key", "s3cret")
    try:
        check_key_is_required(s, "s3cret")
    finally:
        assert s.stop() == 0


def test_the_key_may_come_from_the_environment():
    s = ServerProcess("--host", "0.0.0.0", env=dict(os.environ, NPFKCT_API_KEY="from-env"))
    try:
        check_key_is_required(s, "from-env")
    finally:
        assert s.stop() == 0


def test_loopback_needs_no_key(server):
    assert requests.get(server.url + "/v1/sessions", timeout=10).status_code == 200

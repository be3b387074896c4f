"""Authentication: npfkct-server does not open its API to the network without a key unless told
--insecure; with --api-key (or NPFKCT_API_KEY) /v1 needs the bearer token and health and metrics
do not."""

import json
import os
import subprocess
import sys

import requests

from conftest import ROOT, SERVER_BIN, ServerProcess, world_of


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


def test_a_robot_with_the_key_is_served_through_a_flood_of_unauthenticated_connections():
    """An outside check held 520 idle connections without a key open: every client, robots with
    the key included, got 429 for as long as they stayed. At the limit a newcomer now takes the
    place of a connection that never carried the key (lingering after a refusal, idle, or still
    sending its head; oldest first), and a connection that carried it is never closed for one."""
    import http.client
    import socket

    key = "fl00d"
    good = {"Authorization": "Bearer " + key}
    s = ServerProcess("--api-key", key, "--max-connections", "32")
    flood = []
    try:
        # A robot's keep-alive connection, used once with the key before the flood.
        robot = http.client.HTTPConnection("127.0.0.1", s.port, timeout=30)
        robot.request("GET", "/v1/sessions", headers=good)
        first = robot.getresponse()
        assert first.status == 200 and first.read()
        # 96 idle connections, 24 sending half a head, 24 refused bodies lingering: three times
        # the limit.
        for i in range(96):
            flood.append(socket.create_connection(("127.0.0.1", s.port), timeout=10))
        for i in range(24):
            c = socket.create_connection(("127.0.0.1", s.port), timeout=10)
            c.sendall(b"GET /v1/sessions HTTP/1.1\r\nHost: x\r\n")
            flood.append(c)
        for i in range(24):
            c = socket.create_connection(("127.0.0.1", s.port), timeout=10)
            c.sendall(b"POST /v1/sessions HTTP/1.1\r\nHost: x\r\nContent-Length: 1000000\r\n\r\n")
            flood.append(c)
        # The robot's connection is still open and serves its next request.
        robot.request("GET", "/v1/sessions", headers=good)
        again = robot.getresponse()
        assert again.status == 200 and again.read()
        # A robot connecting now is served: a session created and a plan made.
        created = requests.post(s.url + "/v1/sessions", headers=good, timeout=30,
                                json={"world": world_of("loose1"), "seed": 1})
        assert created.status_code == 200, created.text
        sid = created.json()["id"]
        plan = requests.post(f"{s.url}/v1/sessions/{sid}:plan", headers=good, timeout=60,
                             json={"budget": {"cpuMs": 50}})
        assert plan.status_code == 200, plan.text
        assert requests.get(s.url + "/healthz", timeout=10).status_code == 200
        # The flood's connections were closed one for each newcomer; the server still holds at
        # most its limit, so at least len(flood) - 32 of them were closed.
        closed = 0
        for c in flood:
            c.settimeout(0.5)
            try:
                closed += c.recv(65536) == b"" or c.recv(65536) == b""
            except (ConnectionResetError, socket.timeout, BrokenPipeError):
                closed += 0
        assert closed >= len(flood) - 32 - 4, closed
        robot.close()
        assert s.alive()
    finally:
        for c in flood:
            c.close()
        assert s.stop() == 0


def test_the_python_sdk_and_cli_take_the_server_and_key_from_the_environment():
    key = "env-k3y"
    s = ServerProcess("--api-key", key)
    try:
        env = dict(os.environ, NPFKCT_SERVER=s.url, NPFKCT_API_KEY=key,
                   PYTHONPATH=os.path.join(ROOT, "clients", "python"))
        sdk = ("from npfkct_client import NpfkctClient, World\n"
               "c = NpfkctClient()\n"
               "with c.create_session(World.from_scenario('scenarios/loose1.json')) as s:\n"
               "    print(s.id, len(c.list_sessions()))\n")
        out = subprocess.run([sys.executable, "-c", sdk], cwd=ROOT, env=env, capture_output=True,
                             text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        assert out.stdout.split()[1] == "1"
        cli = subprocess.run([sys.executable, "-m", "npfkct_client", "list"], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=60)
        assert cli.returncode == 0, cli.stderr
        assert json.loads(cli.stdout) == {"sessions": []}
        # Without the key the same command is refused by the server, naming the header.
        env.pop("NPFKCT_API_KEY")
        cli = subprocess.run([sys.executable, "-m", "npfkct_client", "list"], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=60)
        assert cli.returncode == 1 and "UNAUTHENTICATED" in cli.stderr, cli.stderr
    finally:
        assert s.stop() == 0

"""The clients against a hostile server: a real HTTP server on a loopback socket that answers
with wrong types, endless or huge bodies, a byte at a time, page tokens in a circle, odd
Retry-After values, or an action id made to break out of a script. Each client must end with an
error of its own (not an abort, a hang or unbounded memory) and never run what the server sent."""

import json
import os
import resource
import socket
import subprocess
import sys
import threading
import time

import pytest

from conftest import BUILD, ROBOT_BIN, ROOT, scenario_path

from npfkct_client import ApiError, NpfkctClient

DRIVE = os.path.join(BUILD, "bin", "npfkct-drive")
CURL = os.path.join(ROOT, "clients", "curl")
sys.path.insert(0, os.path.join(ROOT, "clients", "ros", "npfkct_ros", "src"))

SESSION = {"id": "s1", "displayName": "", "planner": {"name": "kct"}, "state": "READY",
           "steps": 0, "createTime": "2026-01-01T00:00:00Z", "updateTime": "2026-01-01T00:00:00Z"}
LOOK = {"actionId": "a1", "action": {"type": "LOOK"}, "expectedValue": 0.0,
        "stats": {"simulations": 1}, "session": dict(SESSION, state="ACTION_PENDING")}


# Replies that never end: the head sent first, then the piece again and again (pause in s).
ENDLESS = {
    "huge": (b"HTTP/1.1 200 OK\r\nContent-Length: 68719476736\r\n\r\n", b"0" * (1 << 20), 0),
    "endless-chunks": (b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n",
                       b"100000\r\n" + b" " * 0x100000 + b"\r\n", 0),
    "drip": (b"HTTP/1.1 200 OK\r\nContent-Length: 1000\r\n\r\n", b" ", 0.5),
    "head-drip": (b"HTTP/1.1 200 OK\r\n", b"X", 0.5),
    "endless-continue": (b"", b"HTTP/1.1 100 Continue\r\n\r\n", 0.2),
    "header-flood": (b"HTTP/1.1 200 OK\r\n", b"X-A: " + b"b" * 8000 + b"\r\n", 0),
    "endless-header-line": (b"HTTP/1.1 200 OK\r\nX-A: ", b"c" * 65536, 0),
    # requests read a redirect's body whole before anything could count it.
    "redirect": (b"HTTP/1.1 302 Found\r\nLocation: /v1/sessions/s2\r\n"
                 b"Content-Length: 68719476736\r\n\r\n", b"0" * (1 << 20), 0),
}


class HostileServer:
    """Answers every request by `mode`; `received` keeps (method, path, body) of each."""

    def __init__(self, mode):
        self.mode = mode
        self.received = []
        if mode == "gzip-gzip":
            # 64 MiB of spaces compressed twice, made before the server answers: compressing
            # takes seconds of CPU on a loaded machine, which must not count against the
            # client's deadline.
            import gzip
            self.gzip_gzip = gzip.compress(gzip.compress(b" " * (64 << 20)))
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.url = "http://127.0.0.1:%d" % self.sock.getsockname()[1]
        self.stopping = False
        threading.Thread(target=self._serve, daemon=True).start()

    def close(self):
        self.stopping = True
        self.sock.close()

    def _serve(self):
        while not self.stopping:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            threading.Thread(target=self._handle, args=(conn,), daemon=True).start()

    def _handle(self, conn):
        try:
            with conn:
                conn.settimeout(30)
                data = b""
                while b"\r\n\r\n" not in data:
                    chunk = conn.recv(65536)
                    if not chunk:
                        return
                    data += chunk
                head, _, body = data.partition(b"\r\n\r\n")
                lines = head.decode("latin-1").split("\r\n")
                method, path = lines[0].split(" ")[:2]
                length = 0
                for line in lines[1:]:
                    if line.lower().startswith("content-length:"):
                        length = int(line.split(":")[1])
                while len(body) < length:
                    body += conn.recv(65536)
                self.received.append((method, path, body))
                self._answer(conn, method, path)
        except OSError:
            pass

    @staticmethod
    def _json(conn, status, value, extra=""):
        body = value if isinstance(value, bytes) else json.dumps(value).encode()
        conn.sendall(b"HTTP/1.1 %d X\r\nContent-Type: application/json\r\n%sContent-Length: %d"
                     b"\r\nConnection: close\r\n\r\n" % (status, extra.encode(), len(body)) + body)

    def _answer(self, conn, method, path):
        mode = self.mode
        if mode == "inject":
            if path.endswith(":plan"):
                # An action id that would end a quoted Python string and run code.
                payload = dict(LOOK, actionId="x'; open(__import__('os').environ['PWN'], 'w')"
                                              ".write('pwned'); z='")
                return self._json(conn, 200 if len(self.received) < 3 else 400, payload)
            return self._json(conn, 200, dict(SESSION) if path == "/v1/sessions" else {})
        if mode == "wrong-types":
            return self._json(conn, 200, {"id": 5, "planner": [1], "action": 7})
        if mode == "array":
            return self._json(conn, 200, [1, 2, 3])
        if mode == "odd-error":
            return self._json(conn, 400, {"error": {"status": 5, "message": [1],
                                                    "details": [{"fieldViolations": "x"}, 3]}})
        if mode == "deep":
            return self._json(conn, 200, b"[" * 200000 + b"]" * 200000)
        if mode in ENDLESS:
            head, piece, pause = ENDLESS[mode]
            conn.sendall(head)
            while True:
                conn.sendall(piece)
                time.sleep(pause)
        if mode == "long-status":
            return conn.sendall(b"HTTP/1.1 200 " + b"a" * 60000 + b"\r\n\r\n")
        if mode == "gzip-gzip":
            return self._json(conn, 200, self.gzip_gzip, "Content-Encoding: gzip, gzip\r\n")
        if mode == "big-number":
            return self._json(conn, 200, b'{"id": "s1", "robot": {"x": 1' + b"0" * 400 + b"}}")
        if mode == "page-loop":
            return self._json(conn, 200, {"sessions": [], "nextPageToken": "again"})
        if mode.startswith("retry-after:"):
            return self._json(conn, 429, {"error": {"status": "RESOURCE_EXHAUSTED",
                                                    "message": "busy", "details": []}},
                              "Retry-After: %s\r\n" % mode.split(":", 1)[1])
        raise AssertionError(mode)


@pytest.fixture
def hostile():
    servers = []

    def start(mode):
        servers.append(HostileServer(mode))
        return servers[-1]

    yield start
    for s in servers:
        s.close()


def limited(gib):
    """preexec_fn: an address-space cap, so that a client that keeps a huge reply fails fast."""
    return lambda: resource.setrlimit(resource.RLIMIT_AS, (gib << 30, gib << 30))


@pytest.mark.parametrize("mode", ["wrong-types", "array", "odd-error", "deep", "huge",
                                  "endless-chunks", "drip", "head-drip", "endless-continue",
                                  "long-status", "header-flood", "endless-header-line",
                                  "redirect"])
def test_the_driver_ends_with_an_error_of_its_own(hostile, mode):
    server = hostile(mode)
    t = time.monotonic()
    r = subprocess.run([DRIVE, "--server", server.url, "--scenario", scenario_path("loose1"),
                        "--budget-ms", "10", "--timeout", "3"], capture_output=True, text=True,
                       timeout=60, preexec_fn=limited(2))
    # 1: an error it names; an abort (negative: a signal) or bad_alloc is a crash.
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])
    assert "npfkct-drive:" in r.stderr and "terminate" not in r.stderr
    assert time.monotonic() - t < 30


def test_the_driver_refuses_a_timeout_it_cannot_keep():
    for timeout in ["nan", "0", "-1", "inf", "1e300"]:
        r = subprocess.run([DRIVE, "--server", "http://127.0.0.1:1", "--scenario",
                            scenario_path("loose1"), "--timeout", timeout],
                           capture_output=True, text=True, timeout=30)
        assert r.returncode != 0 and "--timeout" in r.stderr, (timeout, r.stderr)
        assert "Couldn't connect" not in r.stderr  # refused before any call


@pytest.mark.parametrize("mode,status", [("wrong-types", "DATA_LOSS"), ("array", "DATA_LOSS"),
                                         ("odd-error", "UNKNOWN"), ("deep", "DATA_LOSS"),
                                         ("huge", "RESOURCE_EXHAUSTED"),
                                         ("endless-chunks", "RESOURCE_EXHAUSTED"),
                                         ("drip", "DEADLINE_EXCEEDED"),
                                         ("head-drip", "DEADLINE_EXCEEDED"),
                                         ("endless-continue", "DEADLINE_EXCEEDED"),
                                         ("gzip-gzip", "DATA_LOSS"), ("big-number", "DATA_LOSS"),
                                         ("redirect", "UNKNOWN")])
def test_the_python_client_raises_api_errors(hostile, mode, status):
    server = hostile(mode)
    client = NpfkctClient(server.url, timeout=3, max_reply_bytes=8 << 20)
    t = time.monotonic()
    with pytest.raises(ApiError) as e:
        client.get_session("s1")
    assert e.value.status == status, e.value
    assert time.monotonic() - t < 30


def test_the_python_client_refuses_timeouts_it_cannot_keep():
    for timeout in [0, -1, float("nan"), float("inf"), 1e10, None]:
        with pytest.raises(ValueError):
            NpfkctClient("http://127.0.0.1:1", timeout=timeout)


def test_the_python_client_stops_at_page_tokens_in_a_circle(hostile):
    client = NpfkctClient(hostile("page-loop").url, timeout=3)
    with pytest.raises(ApiError) as e:
        client.list_sessions()
    assert e.value.status == "DATA_LOSS"


@pytest.mark.parametrize("value,expected", [("nan", None), ("inf", None), ("-3", 0.0),
                                            ("2", 2.0), ("soon", None),
                                            ("Wed, 21 Oct 2015 07:28:00 GMT", 0.0)])
def test_retry_after_as_seconds_or_a_date(hostile, value, expected):
    client = NpfkctClient(hostile("retry-after:" + value).url, timeout=3)
    with pytest.raises(ApiError) as e:
        client.get_session("s1")
    assert e.value.http_status == 429 and e.value.retry_after == expected
    from npfkct_ros import retry
    # The ROS node's wait stays a finite delay whatever the header held.
    assert retry.RetryPolicy(3, 0.2, 5.0).delay(0, float("nan")) == 0.2


def test_the_curl_episode_never_runs_what_the_server_sends(hostile, tmp_path):
    server = hostile("inject")
    marker = tmp_path / "pwned"
    env = dict(os.environ, NPFKCT_SERVER=server.url, PWN=str(marker))
    r = subprocess.run([os.path.join(CURL, "episode.sh"), scenario_path("loose1"), ROBOT_BIN,
                        "10"], env=env, capture_output=True, text=True, timeout=120)
    assert not marker.exists(), r.stdout + r.stderr
    observes = [json.loads(b) for m, p, b in server.received if p.endswith(":observe")]
    assert observes and observes[0]["actionId"].startswith("x'; open(")
    assert r.returncode != 0  # the second plan's 400 ends the episode

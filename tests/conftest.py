"""Shared fixtures: the real npfkct-server on a loopback port, the simulated robot, paths."""

import base64
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.environ.get("NPFKCT_BUILD_DIR", os.path.join(ROOT, "build"))
SERVER_BIN = os.environ.get("NPFKCT_SERVER_BIN", os.path.join(BUILD, "bin", "npfkct-server"))
ROBOT_BIN = os.path.join(BUILD, "bin", "npfkct-sim-robot")
SCENARIOS = os.path.join(ROOT, "scenarios")
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))


def free_port():
    """A loopback port that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop_process(proc, sig, timeout):
    """Sends `sig` to a running `proc`, waits up to `timeout` seconds, then kills it; returns the
    exit status."""
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode


def scenario_path(name):
    return os.path.join(SCENARIOS, name + ".json")


def world_of(name):
    """The prior-map part of a scenario file: what a robot tells the server."""
    from npfkct_client import World
    return World.from_scenario(scenario_path(name))


class ServerProcess:
    """npfkct-server started on a free port; stop() ends it (SIGTERM, or SIGKILL with kill()).
    Its output is drained by background threads (a full pipe would block the server) and kept in
    `output` for the tests to inspect."""

    started = []  # every server started; kill_servers_a_test_left kills a test's leftovers

    def __init__(self, *args, binary=SERVER_BIN, preexec_fn=None, env=None):
        self.proc = subprocess.Popen([binary, "--port", "0", "--log-level", "warn", *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     errors="replace", preexec_fn=preexec_fn, env=env)
        line, skipped = self.proc.stdout.readline(), []
        while line and not line.startswith("listening on") and len(skipped) < 1000:
            skipped.append(line)
            line = self.proc.stdout.readline()
        if not line.startswith("listening on"):
            self.proc.kill()
            raise RuntimeError("server did not start: " + "".join(skipped) + line +
                               self.proc.stderr.read())
        ServerProcess.started.append(self)
        self.port = int(line.strip().rsplit(":", 1)[1])
        self.url = f"http://127.0.0.1:{self.port}"
        self.output = []
        for stream in (self.proc.stdout, self.proc.stderr):
            threading.Thread(target=self._drain, args=(stream,), daemon=True).start()

    def _drain(self, stream):
        for line in stream:
            self.output.append(line)

    def alive(self):
        return self.proc.poll() is None

    def stop(self):
        """SIGTERM, then the exit status (0 for an orderly shutdown; under the sanitizers, not 0
        when they found something, leaks included)."""
        return stop_process(self.proc, signal.SIGTERM, 30)

    def kill(self):
        self.proc.kill()
        self.proc.wait()


@pytest.fixture(autouse=True)
def kill_servers_a_test_left():
    """Kills the servers a test started and left running (a failed assertion skips its stop());
    servers of wider-scoped fixtures, started before the test, are left to their fixtures."""
    before = len(ServerProcess.started)
    yield
    for server in ServerProcess.started[before:]:
        if server.alive():
            server.kill()
    del ServerProcess.started[before:]


class SimRobot:
    """npfkct-sim-robot: executes API actions and returns :observe bodies."""

    def __init__(self, scenario, seed=1, raw=False, boxes=False, boxes3d=False):
        args = [ROBOT_BIN, "--scenario", scenario_path(scenario), "--seed", str(seed)]
        mode = [flag for flag, on in (("--raw", raw), ("--boxes", boxes), ("--boxes3d", boxes3d))
                if on]
        self.proc = subprocess.Popen(args + mode,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.photos_args = args + ["--target-photos"]

    def target_photos(self):
        """The target's photos as PNG bytes."""
        out = subprocess.run(self.photos_args, check=True, capture_output=True, text=True).stdout
        return [base64.b64decode(p) for p in json.loads(out)]

    def execute(self, action):
        self.proc.stdin.write(json.dumps(action) + "\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

    def close(self):
        self.proc.stdin.close()
        self.proc.wait(timeout=10)


@pytest.fixture
def server():
    s = ServerProcess()
    yield s
    s.stop()


def wait_for(predicate, timeout=10.0, interval=0.05):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return False


def npm_tool(source_dir, name):
    """A Node.js tool of the tests (source_dir: its package.json, package-lock.json and scripts)
    with its node_modules, installed with `npm ci` into BUILD/name once per lock file; returns
    that directory, which holds copies of the tool's scripts."""
    import shutil
    for tool in ("node", "npm"):
        if not shutil.which(tool):
            pytest.fail(f"{tool} is not installed (scripts/deps.sh installs nodejs and npm)")
    import fcntl
    work = os.path.join(BUILD, name)
    os.makedirs(work, exist_ok=True)
    with open(os.path.join(source_dir, "package-lock.json"), encoding="utf-8") as f:
        lock = f.read()
    stamp = os.path.join(work, "node_modules", ".npfkct-lock")
    # ctest runs test files in parallel: one installs while the others wait for it.
    with open(work + ".lock", "w", encoding="utf-8") as guard:
        fcntl.flock(guard, fcntl.LOCK_EX)
        if not os.path.exists(stamp) or open(stamp, encoding="utf-8").read() != lock:
            for file in ("package.json", "package-lock.json"):
                shutil.copy(os.path.join(source_dir, file), work)
            subprocess.run(["npm", "ci", "--no-audit", "--no-fund", "--loglevel=error"],
                           cwd=work, check=True, capture_output=True, timeout=900)
            with open(stamp, "w", encoding="utf-8") as f:
                f.write(lock)
        for file in os.listdir(source_dir):
            if file.endswith((".mjs", ".js", ".yaml")):
                shutil.copy(os.path.join(source_dir, file), work)
    return work

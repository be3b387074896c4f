"""A fleet on loopback for tests and benchmarks: a throwaway PostgreSQL cluster, npfkct-server
replicas sharing it (--store), and Debian's nginx routing with deploy/nginx/npfkct.conf."""

import glob
import os
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import time

import requests

from conftest import ROOT, ServerProcess, free_port, stop_process

NGINX_CONF = os.path.join(ROOT, "deploy", "nginx", "npfkct.conf")


def _as_postgres():
    """initdb and postgres refuse to run as root: as root, they run as the postgres user that
    Debian's package creates. (Switched by subprocess itself rather than runuser, whose
    supervising parent stops itself when postgres is stopped and would sit between the test and
    the postmaster.)"""
    if os.geteuid() == 0:
        return {"user": "postgres", "group": "postgres", "extra_groups": []}
    return {}


def pg_bin(name):
    found = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"))
    if not found:
        raise RuntimeError(f"PostgreSQL's {name} is not installed (Debian: postgresql)")
    return found[-1]


class Postgres:
    """A PostgreSQL cluster in a temporary directory, listening on 127.0.0.1 only, with trust
    authentication, started by the caller and removed by remove()."""

    def __init__(self):
        self.dir = tempfile.mkdtemp(prefix="npfkct-pg-")
        os.chmod(self.dir, 0o755)
        self.data = os.path.join(self.dir, "data")
        if os.geteuid() == 0:
            shutil.chown(self.dir, "postgres", "postgres")
        subprocess.run([pg_bin("initdb"), "-D", self.data, "-U", "postgres", "--auth=trust",
                        "-E", "UTF8", "--no-sync"], check=True, capture_output=True,
                       cwd=self.dir, **_as_postgres())
        self.port = free_port()
        self.proc = None
        self.start()

    def start(self):
        # The log goes to a file: a pipe nobody reads would stall postgres once full.
        self.log = os.path.join(self.dir, "postgres.log")
        with open(self.log, "a", encoding="utf-8") as log:
            self.proc = subprocess.Popen(
                [pg_bin("postgres"), "-D", self.data, "-p", str(self.port),
                 "-c", "listen_addresses=127.0.0.1", "-c", f"unix_socket_directories={self.dir}",
                 "-c", "fsync=off", "-c", "max_connections=100"],
                stdout=subprocess.DEVNULL, stderr=log, start_new_session=True, cwd=self.dir,
                **_as_postgres())
        deadline = time.time() + 60
        while time.time() < deadline:
            r = subprocess.run([pg_bin("pg_isready"), "-h", "127.0.0.1", "-p", str(self.port)],
                               capture_output=True)
            if r.returncode == 0:
                return
            if self.proc.poll() is not None:
                with open(self.log, encoding="utf-8", errors="replace") as log:
                    raise RuntimeError("postgres did not start: " + log.read()[-3000:])
            time.sleep(0.1)
        raise RuntimeError("postgres did not answer within 60 s")

    def url(self, db="postgres"):
        return f"postgresql://postgres@127.0.0.1:{self.port}/{db}"

    def psql(self, sql, db="postgres"):
        """Runs SQL with psql; returns the rows as lists of strings (unaligned, '|'-separated)."""
        out = subprocess.run(["psql", "-X", "-q", "-A", "-t", "-v", "ON_ERROR_STOP=1", "-d",
                              self.url(db), "-c", sql], check=True, capture_output=True,
                             text=True).stdout
        return [line.split("|") for line in out.splitlines() if line]

    def create_database(self, name):
        self.psql(f"CREATE DATABASE {name}")
        return self.url(name)

    def pids(self):
        """The postmaster and its children. (Each backend makes itself a process group leader,
        so signalling the postmaster's group would not reach them.)"""
        try:
            with open(os.path.join(self.data, "postmaster.pid"), encoding="utf-8") as f:
                postmaster = int(f.readline())
        except (OSError, ValueError):
            return []
        children = []
        for entry in os.listdir("/proc"):
            if not entry.isdigit():
                continue
            try:
                with open(f"/proc/{entry}/stat", encoding="utf-8") as f:
                    stat = f.read()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == postmaster:
                children.append(int(entry))
        return [postmaster] + children

    def signal(self, sig):
        """Sends `sig` to the postmaster and every backend."""
        for pid in self.pids():
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass

    def stop(self, fast=True):
        """Fast shutdown (SIGINT to the postmaster), or with fast=False a crash: SIGKILL to the
        postmaster and every backend."""
        pids = []
        if self.proc and self.proc.poll() is None:
            self.signal(signal.SIGCONT)
            pids = self.pids()
            if fast and pids:
                os.kill(pids[0], signal.SIGINT)
            else:
                self.signal(signal.SIGKILL)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.proc.wait()
        if not fast:
            # A killed postmaster leaves its pid file: the next start must not see one alive.
            deadline = time.time() + 10
            while time.time() < deadline and any(os.path.exists(f"/proc/{p}") for p in pids):
                time.sleep(0.05)

    def remove(self):
        self.stop()
        shutil.rmtree(self.dir, ignore_errors=True)


class Nginx:
    """Debian's nginx with deploy/nginx/npfkct.conf, its replicas and listening port replaced by
    loopback ones (nothing else of the file is changed)."""

    def __init__(self, replica_ports, fail_timeout=None):
        self.dir = tempfile.mkdtemp(prefix="npfkct-nginx-")
        os.chmod(self.dir, 0o755)
        self.port = free_port()
        conf = open(NGINX_CONF, encoding="utf-8").read()
        servers = "".join(f"    server 127.0.0.1:{p} max_fails=1 fail_timeout=10s;\n"
                          for p in replica_ports)
        conf, n = re.subn(r"(?m)^    server replica\d+:8080 .*\n(    server replica.*\n)*",
                          servers, conf)
        assert n == 1, "deploy/nginx/npfkct.conf: the upstream servers were not found"
        conf, n = re.subn(r"(?m)^    listen 8080;$", f"    listen 127.0.0.1:{self.port};", conf)
        assert n == 1, "deploy/nginx/npfkct.conf: 'listen 8080;' was not found"
        if fail_timeout:
            conf = conf.replace("fail_timeout=10s", f"fail_timeout={fail_timeout}")
        with open(os.path.join(self.dir, "npfkct.conf"), "w", encoding="utf-8") as f:
            f.write(conf)
        d = self.dir
        with open(os.path.join(d, "nginx.conf"), "w", encoding="utf-8") as f:
            f.write(f"""daemon off;
worker_processes 1;
pid {d}/nginx.pid;
error_log {d}/error.log warn;
events {{ worker_connections 1024; }}
http {{
    access_log {d}/access.log;
    client_body_temp_path {d}/body;
    proxy_temp_path {d}/proxy;
    fastcgi_temp_path {d}/fastcgi;
    uwsgi_temp_path {d}/uwsgi;
    scgi_temp_path {d}/scgi;
    include {d}/npfkct.conf;
}}
""")
        nginx = shutil.which("nginx") or "/usr/sbin/nginx"
        check = subprocess.run([nginx, "-t", "-p", d, "-c", f"{d}/nginx.conf"],
                               capture_output=True, text=True)
        if check.returncode != 0:
            raise RuntimeError("nginx -t: " + check.stderr)
        self.proc = subprocess.Popen([nginx, "-p", d, "-c", f"{d}/nginx.conf"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.url = f"http://127.0.0.1:{self.port}"
        deadline = time.time() + 30
        while time.time() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                return
            except OSError:
                time.sleep(0.05)
        raise RuntimeError("nginx did not start")

    def error_log(self):
        try:
            return open(os.path.join(self.dir, "error.log"), encoding="utf-8").read()
        except OSError:
            return ""

    def stop(self):
        stop_process(self.proc, signal.SIGQUIT, 10)
        shutil.rmtree(self.dir, ignore_errors=True)


def start_replica(store_url, *args, **kwargs):
    """An npfkct-server replica of the fleet on a free port."""
    return ServerProcess("--store", store_url, *args, **kwargs)


def metric(url, name, labels=None):
    """The value of one metric line of a replica's /metrics (0 when absent)."""
    text = requests.get(url + "/metrics", timeout=10).text
    for line in text.splitlines():
        if line.startswith(name + (("{" + labels + "}") if labels else " ")):
            return float(line.rsplit(" ", 1)[1])
    return 0.0


def call(method, url, deadline, **kwargs):
    """One API call that retries what a client of a fleet retries (connection errors, 502, 503,
    504, 409 ABORTED, 429 after its Retry-After) until `deadline`; returns the final response
    (2xx, or an error that is not worth retrying). Each retry is counted in call.retries."""
    while True:
        delay = 0.2
        try:
            r = requests.request(method, url, timeout=120, **kwargs)
            # A replica killed while it sent its reply leaves nginx a status line and part of the
            # body (urllib3 1.26 does not check the length): a transport error, retried.
            if r.ok and "json" in r.headers.get("Content-Type", ""):
                try:
                    r.json()
                except ValueError:
                    raise requests.ConnectionError(f"{method} {url}: a truncated reply") from None
            if r.status_code not in (409, 429, 502, 503, 504):
                return r
            if r.status_code == 429:
                delay = min(float(r.headers.get("Retry-After", "1")), 5.0)
        except requests.RequestException:
            r = None
        call.retries += 1
        if time.time() > deadline:
            if r is None:
                raise RuntimeError(f"{method} {url}: no answer before the deadline")
            return r
        time.sleep(delay)


call.retries = 0


class FleetRobot:
    """A simulated robot searching through the fleet: plans, executes with npfkct-sim-robot,
    observes, until the target is removed or 50 steps. It checks, before every plan, that the
    belief served is the one last acknowledged (whichever replica serves it), and recovers
    from a reply the fleet lost: a plan saved whose reply was lost is read back from the
    session (pendingAction), an observation saved whose reply was lost is FAILED_PRECONDITION
    "already observed" with the session one step further."""

    def __init__(self, url, scenario, seed, planner="pomcp", budget=None, model=None,
                 sim_robot=None, deadline_s=600):
        from conftest import SimRobot, world_of
        self.url, self.seed = url, seed
        self.robot = sim_robot or SimRobot(scenario, seed=seed)
        self.deadline = time.time() + deadline_s
        self.budget = budget or {"cpuMs": 100}
        spec = {"name": planner}
        if model:
            spec["model"] = model
        r = call("POST", url + "/v1/sessions", self.deadline,
                 json={"world": world_of(scenario), "seed": seed, "planner": spec})
        assert r.status_code == 200, r.text
        self.id = r.json()["id"]
        self.steps = 0
        self.done = False
        self.acked_belief = self.belief()
        self.plan_latencies = []  # (client-seen seconds, planner's elapsedMs / 1000)
        self.recovered = []       # what was recovered from a lost reply
        self.belief_mismatches = []
        self.observed = set()          # actionIds whose observation was acknowledged
        self.lost_observations = []    # (step, actionId) served as pending again
        self.events = []          # (time, step) of every acknowledged observation

    def session_url(self):
        return f"{self.url}/v1/sessions/{self.id}"

    def belief(self):
        r = call("GET", self.session_url() + "/belief", self.deadline)
        assert r.status_code == 200, r.text
        return r.json()

    def plan(self):
        t0 = time.perf_counter()
        r = call("POST", self.session_url() + ":plan", self.deadline,
                 json={"budget": self.budget})
        if r.status_code == 200:
            j = r.json()
            self.plan_latencies.append((time.perf_counter() - t0, j["stats"]["elapsedMs"] / 1e3))
            return j["actionId"], j["action"]
        if r.status_code == 400 and "is pending" in r.text:
            # The plan was saved by a replica whose reply never came: read it back.
            s = call("GET", self.session_url(), self.deadline).json()
            pending = s["pendingAction"]["actionId"]
            # An action this robot already executed and had its observation acknowledged is
            # pending again only when that observation was lost.
            if pending in self.observed:
                self.lost_observations.append((self.steps, pending))
            self.recovered.append(("plan", self.steps))
            return pending, s["pendingAction"]["action"]
        raise AssertionError(f":plan {r.status_code} {r.text}")

    def observe(self, action_id, body):
        r = call("POST", self.session_url() + ":observe", self.deadline,
                 json=dict(body, actionId=action_id))
        if r.status_code == 200:
            self.observed.add(action_id)
            return r.json()["done"]
        if r.status_code == 400 and "already observed" in r.text:
            self.observed.add(action_id)
            s = call("GET", self.session_url(), self.deadline).json()
            assert s["step"] == self.steps + 1, s
            self.recovered.append(("observe", self.steps))
            return s["state"] == "DONE"
        raise AssertionError(f":observe {r.status_code} {r.text}")

    def step(self):
        # Whatever replica serves the session now must serve the belief last acknowledged.
        served = self.belief()
        if served != self.acked_belief:
            self.belief_mismatches.append(self.steps)
        action_id, action = self.plan()
        outcome = self.robot.execute(action)
        self.done = self.observe(action_id, outcome["observation"])
        self.steps += 1
        self.events.append((time.time(), self.steps))
        self.acked_belief = self.belief()

    def run(self, max_steps=50):
        while not self.done and self.steps < max_steps:
            self.step()
        self.robot.close()
        return self

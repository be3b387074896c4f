"""The hostile suite: every class of attack on the server, each against the real server.

Every test holds the server to the same contract: no crash, no 5xx, no hang, clear errors naming
the field, and every session that existed before an attack intact after it. scripts/test.sh runs
this file against the AddressSanitizer/UBSan build (NPFKCT_SERVER_BIN); the memory-bomb test runs
the Release build under an address-space cap (ASan reserves terabytes of address space, so it
cannot run capped): NPFKCT_RELEASE_SERVER_BIN, default build/bin/npfkct-server."""

import base64
import concurrent.futures
import json
import os
import random
import resource
import select
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
import zlib

import pytest
import requests

from conftest import BUILD, ROOT, SERVER_BIN, ServerProcess, SimRobot, world_of

RELEASE_BIN = os.environ.get("NPFKCT_RELEASE_SERVER_BIN",
                             os.path.join(BUILD, "bin", "npfkct-server"))
SANITIZED = SERVER_BIN != RELEASE_BIN
# Health must never wait behind plans (2.5 s each here), slow clients or a full accept queue (a
# dropped SYN costs 1 s): the bound sits well below both and well above a loaded 2-core CI
# machine running the sanitized build, which is several times slower.
HEALTH_BOUND = 0.5


# ---- helpers ----

class Recorder:
    """Every response a test got: none may be a 5xx."""

    def __init__(self):
        self.codes = []
        self.lock = threading.Lock()

    def add(self, code, what=""):
        with self.lock:
            self.codes.append((code, what))

    def check(self):
        fivexx = [(c, w) for c, w in self.codes if c >= 500]
        assert not fivexx, fivexx[:5]


def http(method, url, recorder=None, **kw):
    kw.setdefault("timeout", 60)
    r = requests.request(method, url, **kw)
    if recorder is not None:
        recorder.add(r.status_code, f"{method} {url}")
    if r.status_code >= 400:
        body = r.json()  # every error is the JSON error body
        assert set(body["error"]) == {"code", "status", "message", "details"}, r.text
        assert body["error"]["code"] == r.status_code
    return r


def field_of(r):
    for detail in r.json()["error"]["details"]:
        for v in detail.get("fieldViolations", []):
            return v["field"]
    return None


def raw_exchange(port, data, timeout=10.0, shutdown=False):
    """Sends raw bytes, returns what the server answers before it closes (or the timeout)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        if shutdown:
            s.shutdown(socket.SHUT_WR)
        out = b""
        try:
            while True:
                chunk = s.recv(65536)
                if not chunk:
                    break
                out += chunk
                if b"\r\n\r\n" in out:
                    head, _, rest = out.partition(b"\r\n\r\n")
                    length = [int(l.split(b":")[1]) for l in head.split(b"\r\n")
                              if l.lower().startswith(b"content-length:")]
                    if length and len(rest) >= length[0]:
                        break
        except socket.timeout:
            pass
        return out


def status_of(reply):
    return int(reply.split(b" ", 2)[1]) if reply.startswith(b"HTTP/1.1 ") else None


def create(url, recorder, scenario="loose1", **extra):
    body = {"world": world_of(scenario), "seed": 1, "planner": {"name": "kct", "particles": 50}}
    body.update(extra)
    r = http("POST", url + "/v1/sessions", recorder, json=body)
    assert r.status_code == 200, r.text
    return r.json()["id"]


def planned(url, recorder, **extra):
    """A new session with a plan pending: its id and the plan's action id."""
    sid = create(url, recorder, **extra)
    plan = http("POST", f"{url}/v1/sessions/{sid}:plan", recorder,
                json={"budget": {"simulations": 20}}).json()
    return sid, plan["actionId"]


def snapshot_of(url, sid):
    """What must survive an attack unchanged: the resource and the belief."""
    s = requests.get(f"{url}/v1/sessions/{sid}", timeout=30).json()
    s.pop("updateTime", None)
    return s, requests.get(f"{url}/v1/sessions/{sid}/belief", timeout=30).json()


def observation(action_id):
    return {"actionId": action_id,
            "robotState": {"x": 0.3, "y": 0, "yaw": 0, "lift": 0.2, "pan": 0, "tilt": 0.4},
            "detections": [{"id": "box", "box": {"center": [1.4, 0, 0.8], "size": [0.1, 0.1, 0.1]},
                            "faces": [{"corner": 1, "score": 0.3}]}]}


def png_header_bomb(width, height):
    """A PNG whose header claims width x height pixels, with a tiny zlib stream of zeros."""
    def chunk(kind, payload):
        return (struct.pack(">I", len(payload)) + kind + payload +
                struct.pack(">I", zlib.crc32(kind + payload)))
    rows = zlib.compress(b"\x00" * 4096, 9)
    return (b"\x89PNG\r\n\x1a\n" +
            chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", rows) + chunk(b"IEND", b""))


def cloud_bytes(points):
    return b"".join(struct.pack("<fff", *p) for p in points)


def raw_observation(action_id, points, frame="camera"):
    return {"actionId": action_id,
            "robotState": {"x": 0.3, "y": 0, "yaw": 0, "lift": 0.2, "pan": 0, "tilt": 0.4},
            "pointCloud": {"frame": frame, "fields": "xyz",
                           "data": base64.b64encode(cloud_bytes(points)).decode()}}


def example(name):
    """A body of schemas/examples, parsed."""
    with open(os.path.join(ROOT, "schemas", "examples", name), encoding="utf-8") as f:
        return json.load(f)


def three_squares(x, y, z):
    """Three orthogonal 0.6 m squares of points 1 cm apart from the corner (x, y, z): one level,
    two hanging down from it. Before the example session's robot, ICP cannot fit them from the
    reported pose, so RANSAC runs."""
    points = []
    for i in range(60):
        for k in range(60):
            u, v = i * 0.01, k * 0.01
            points += [(x + u, y + v, z), (x, y + u, z - v), (x + u, y, z - v)]
    return points


def registration_edge_points():
    """Twelve map points 5.9 m from raw_observation's robot at (0.3, 0) in x and y: the view as
    wide as registration_range (6 m) lets it be."""
    return [(0.3 + sx * 5.9 + 0.01 * j, sy * 5.9, 0.4)
            for sx in (-1, 1) for sy in (-1, 1) for j in range(3)]


@pytest.fixture
def hostile_server(tmp_path):
    server = ServerProcess("--state-dir", str(tmp_path / "state"), "--max-body-mb", "4",
                           "--head-timeout", "2", "--body-timeout", "3", "--plan-slots", "2",
                           "--plan-queue", "4")
    yield server
    assert_clean_exit(server)


def assert_clean_exit(server):
    code = server.stop()
    assert code == 0, f"exit status {code}:\n" + "".join(server.output[-40:])


def assert_alive_and_intact(server, before, recorder):
    assert server.alive(), "the server crashed:\n" + "".join(server.output[-30:])
    t = time.monotonic()
    assert http("GET", server.url + "/healthz", recorder).status_code == 200
    assert time.monotonic() - t < 5.0
    for sid, (session, belief) in before.items():
        assert snapshot_of(server.url, sid) == (session, belief), sid
    recorder.check()


# ---- 1. huge finite coordinates ----

def test_huge_finite_coordinates_are_refused_before_they_reach_pcl(hostile_server):
    url, rec = hostile_server.url, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    sid, action_id = planned(url, rec)
    good = [(0.01 * i, 0.0, 1.0 + 0.001 * i) for i in range(200)]
    for points, frame in [([(0.0, 0.0, 3e38)] * 3 + good, "camera"),
                          ([(1e37, 1e37, 1e37)] * 3 + good, "map"),
                          ([(-3.4e38, 0.0, 1.0)] + good, "map"),
                          ([(1e4 + 1, 0.0, 1.0)] + good, "camera")]:
        r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec,
                 json=raw_observation(action_id, points, frame))
        assert r.status_code == 400, r.text
        assert field_of(r) == "pointCloud.data"
    for world_edit in [lambda w: w["furniture"][0].__setitem__("center", [1e37, 0]),
                       lambda w: w["baseRegions"][0].__setitem__("min", [-1e308, -1e308]),
                       lambda w: w.__setitem__("start", {"x": 1e300}),
                       lambda w: w.__setitem__("room", {"min": [-1e5, -1e5], "max": [1e5, 1e5]})]:
        world = world_of("loose1")
        world_edit(world)
        r = http("POST", url + "/v1/sessions", rec, json={"world": world})
        assert r.status_code == 400 and field_of(r).startswith("world."), r.text
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec,
             json=dict(observation(action_id),
                       robotState={"x": 1e308, "y": 0, "yaw": 0, "lift": 0, "pan": 0, "tilt": 0}))
    assert r.status_code == 400 and field_of(r) == "robotState.x"
    # The session whose observations were refused still has its action pending and goes on.
    assert http("POST", f"{url}/v1/sessions/{sid}:observe", rec,
                json=observation(action_id)).status_code == 200
    # At the limit, inside it: a real rendered frame with points at 9,999 m reaches PCL (whose
    # voxel grid cannot index such an extent and keeps the points) and is processed. Every second
    # point of the frame is sent, so that a close view's frame stays under this server's 4 MiB
    # body limit whichever views the planner picks.
    robot = SimRobot("loose1", seed=4, raw=True)
    raw = create(url, rec)
    processed = 0
    for _ in range(4):
        plan = http("POST", f"{url}/v1/sessions/{raw}:plan", rec,
                    json={"budget": {"simulations": 30}}).json()
        body = dict(robot.execute(plan["action"])["observation"], actionId=plan["actionId"])
        if "pointCloud" in body:
            extreme = b"".join(struct.pack("<fffI", x, y, z, 0) for x, y, z in
                               [(9999.0, 9999.0, 9999.0), (-9999.0, 9999.0, 0.5),
                                (0.001, -9999.0, 9999.0)])
            frame = base64.b64decode(body["pointCloud"]["data"])
            data = extreme + b"".join(frame[i:i + 16] for i in range(0, len(frame), 32))
            body["pointCloud"] = dict(body["pointCloud"], frame="map",
                                      data=base64.b64encode(data).decode())
        r = http("POST", f"{url}/v1/sessions/{raw}:observe", rec, json=body)
        processed += r.status_code == 200 and "perception" in r.json()
        if r.status_code != 200:
            del body["pointCloud"], body["image"], body["camera"]
            assert http("POST", f"{url}/v1/sessions/{raw}:observe", rec,
                        json=body).status_code == 200
    robot.close()
    assert processed > 0
    assert_alive_and_intact(hostile_server, before, rec)


def test_points_far_away_do_not_switch_off_downsampling(hostile_server):
    """Three points 9,999 m away made PCL's voxel grid (32-bit voxel numbers) return a frame
    unfiltered: a 1 mm blob of 100,000 points then became an object and cost the k-d tree
    searches tens of minutes. Now the blob is one voxel with or without them."""
    url, rec = hostile_server.url, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    rnd = random.Random(5)
    blob = [(1.2 + 0.001 * rnd.random(), -0.3 + 0.001 * rnd.random(), 0.8 + 0.001 * rnd.random())
            for _ in range(100_000)]
    far = [(9999.0, 9999.0, 9999.0), (-9999.0, 9999.0, 0.5), (0.001, -9999.0, 9999.0)]
    clusters = []
    for points in (blob, far + blob):
        sid, action_id = planned(url, rec)
        r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec,
                 json=raw_observation(action_id, points, "map"), timeout=60)
        assert r.status_code == 200, r.text
        clusters.append(r.json()["perception"]["clusters"])
    assert clusters == [0, 0]
    assert_alive_and_intact(hostile_server, before, rec)


def rgb_png(width, height, row_of):
    """An RGB PNG whose row y is row_of(y) (3 * width bytes)."""
    def chunk(kind, payload):
        return (struct.pack(">I", len(payload)) + kind + payload +
                struct.pack(">I", zlib.crc32(kind + payload)))
    comp = zlib.compressobj(9)
    data = b"".join(comp.compress(b"\x00" + row_of(y)) for y in range(height)) + comp.flush()
    return (b"\x89PNG\r\n\x1a\n" +
            chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", data) + chunk(b"IEND", b""))


def flat_png(width, height):
    """One colour: 2048 x 2048 pixels in about 12 kB."""
    row = bytes((120, 80, 40)) * width
    return rgb_png(width, height, lambda y: row)


def noise_png(size, seed=3):
    rnd = random.Random(seed)
    rows = [bytes(rnd.randrange(256) for _ in range(3 * size)) for _ in range(size)]
    return rgb_png(size, size, lambda y: rows[y])


def test_feature_of_points_a_denormal_apart_does_not_abort(hostile_server):
    """A cube off the table (ICP fits it badly, RANSAC runs) and two points 2e-20 m apart across
    a RANSAC voxel boundary: PCL's FPFH weight 1 / squared distance was inf, the feature NaN, and
    the consensus' feature k-d tree asserted: the server aborted on a 0.3 MB frame."""
    url, rec = hostile_server.url, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    sid, action_id = planned(url, rec)
    rnd = random.Random(1)
    points = []
    for _ in range(20000):
        u, v = rnd.uniform(-0.3, 0.3), rnd.uniform(-0.3, 0.3)
        face = rnd.randrange(6)
        a = 0.3 if face % 2 else -0.3
        x, y, z = [(a, u, v), (u, a, v), (u, v, a)][face // 2]
        if not (abs(x) < 0.06 and -1.53 < y - 1.5 < -1.44 and z + 0.6 > 0.87):
            points.append((x, y - 1.5, z + 0.6))
    points += [(1e-20, -1.485, 0.915), (-1e-20, -1.485, 0.915)]
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec,
             json=raw_observation(action_id, points, "map"))
    assert r.status_code == 200, r.text
    # RANSAC ran: it is used, or ICP's fit stayed worse than PerceptionOptions::icp_good_fitness
    # (2.5e-4 m^2), the condition for trying it. Used means kept: the pose was corrected (here its
    # refinement moved the camera more than 0.5 m, was thrown away and was reported as used).
    p = r.json()["perception"]
    assert (p["registration"] == "RANSAC_ICP" or
            (p["registration"] == "ICP" and p["fitness"] > 2.5e-4)), p
    reported = raw_observation(action_id, [])["robotState"]
    if p["registration"] == "RANSAC_ICP":
        assert any(abs(p["robotState"][k] - reported[k]) > 1e-9 for k in ("x", "y", "yaw")), p
    assert_alive_and_intact(hostile_server, before, rec)


def test_the_attack_script_runs():
    """bench/perception_attacks.py, which measured the figures of docs/api.md, on small inputs."""
    script = os.path.join(ROOT, "bench", "perception_attacks.py")
    for attack in (["far-blob", "1000"], ["sift-plates", "3"]):
        out = subprocess.run([sys.executable, script, *attack], capture_output=True, text=True,
                             timeout=300).stdout
        assert f"{attack[0]}: status 200" in out and "server exit status 0" in out, out


def test_sift_work_per_frame_is_bounded(hostile_server):
    """30 thin plates on the camera's axis with fx = 1e6 and a 12 kB 2048 x 2048 image: every
    plate's rectangle is the whole image, and SIFT ran on each (29 s of CPU, 1.2 GB). Regions are
    scaled down to 640 x 480 pixels and SIFT stops at its per-frame budget. With 33 more plates
    beside them the frame has 63 clusters, as many as a session may know; the 64th is refused
    before any of that."""
    url, rec = hostile_server.url, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    photo = base64.b64encode(noise_png(64)).decode()
    for plates, status in [(63, 200), (64, 400)]:
        sid, action_id = planned(url, rec, target={"description": "x", "photos": [photo]})
        # 30 plates on the axis (the table's length), the others beside it, out of the image.
        spots = [(1.025 + 0.04 * (k % 30), (0.005, -0.245, 0.255)[k // 30]) for k in range(plates)]
        points = [(x, y + 0.01 * i, 1.085 + 0.01 * j)
                  for x, y in spots for i in range(-3, 4) for j in range(-3, 3)]
        body = dict(raw_observation(action_id, points, "map"),
                    robotState={"x": 0.3, "y": 0, "yaw": 0, "lift": 0.0, "pan": 0, "tilt": 0.0},
                    camera={"width": 2048, "height": 2048, "fx": 1e6, "fy": 1e6, "cx": 1024,
                            "cy": 1024},
                    image={"data": base64.b64encode(flat_png(2048, 2048)).decode()})
        r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=body, timeout=60)
        assert r.status_code == status, r.text
        if status == 400:
            assert field_of(r) == "pointCloud.data"
            assert "64 object clusters in one frame" in r.text
        else:
            assert r.json()["perception"]["clusters"] == 63
    assert_alive_and_intact(hostile_server, before, rec)


def jpeg_segments(data):
    """A JPEG's segments after its start-of-image marker up to the end-of-image marker, each scan
    with its entropy-coded data (which runs to the next marker that is neither a stuffed zero
    nor a restart marker)."""
    out, i = [], 2
    while data[i + 1] != 0xD9:
        end = i + 2 + struct.unpack(">H", data[i + 2:i + 4])[0]
        if data[i + 1] == 0xDA:
            while not (data[end] == 0xFF and data[end + 1] != 0 and
                       not 0xD0 <= data[end + 1] <= 0xD7):
                end += 1
        out.append(data[i:end])
        i = end
    return out


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat", encoding="utf-8") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_images_that_decode_slowly_for_their_size(hostile_server):
    """Found by an outside attack: (1) a flat 2048 x 2048 progressive JPEG whose 16-byte
    refinement scan is repeated 2,000 times (57 kB): libjpeg passes over the whole image per
    scan, 5.8 s of CPU as a target photo, and as much as the image of an observation on a session
    that does not exist (images were decoded while the body was read, before the lookup). (2) A
    16 x 16 PNG with 300 zTXt chunks each inflating to 7 MB of zeros (2 MB): libpng inflated every
    one, 8.7 s. (3) An arithmetic-coded CMYK JPEG of 32 four-component scans: 725 bytes, 0.8 s.
    Now a JPEG whose scans cover more than 40 components in all, or an arithmetic-coded one, is
    refused naming the field, an observation's image is decoded only for a session that exists,
    and a PNG's text chunks are never read. tests/data/flat_progressive_2048.jpg is
    cv::imencode of a flat grey 2048 x 2048 image with IMWRITE_JPEG_PROGRESSIVE and quality 50
    (10 scans covering 14 components)."""
    url, rec = hostile_server.url, Recorder()
    with open(os.path.join(ROOT, "tests", "data", "flat_progressive_2048.jpg"), "rb") as f:
        progressive = f.read()
    segments = jpeg_segments(progressive)
    scans = [s for s in segments if s[1] == 0xDA]
    assert len(scans) == 10
    head = b"".join(s for s in segments if s[1] != 0xDA)
    refinement = scans[5]  # a 16-byte refinement scan of the luma (libjpeg: 3 ms each)

    def jpeg(extra_scans):
        return b"\xff\xd8" + head + b"".join(scans) + refinement * extra_scans + b"\xff\xd9"

    def photos(*images):
        return {"description": "x", "photos": [base64.b64encode(i).decode() for i in images]}

    pid = hostile_server.proc.pid
    before = cpu_seconds(pid)
    # Within the limit the photo is taken (the decoder makes 36 passes)...
    create(url, rec, target=photos(jpeg(22)))
    # ... beyond it refused, at creation and in an observation.
    r = http("POST", url + "/v1/sessions", rec,
             json={"world": world_of("loose1"), "target": photos(progressive, jpeg(2000))})
    assert r.status_code == 400 and field_of(r) == "target.photos[1]", r.text
    assert "cover more than 40 components" in r.text
    arithmetic = progressive.replace(b"\xff\xc2", b"\xff\xca", 1)  # SOF10: arithmetic-coded
    r = http("POST", url + "/v1/sessions", rec,
             json={"world": world_of("loose1"), "target": photos(arithmetic)})
    assert r.status_code == 400 and "arithmetic-coded" in r.text, r.text
    body = dict(raw_observation("a1-000000", [(1.0, 0.0, 1.0)]),
                camera={"width": 2048, "height": 2048, "fx": 1000, "fy": 1000, "cx": 1024,
                        "cy": 1024},
                image={"encoding": "jpeg", "data": base64.b64encode(jpeg(2000)).decode()})
    r = http("POST", f"{url}/v1/sessions/{'f' * 32}:observe", rec, json=body)
    assert r.status_code == 404, r.text  # not decoded for a session that does not exist
    sid, action_id = planned(url, rec)
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=dict(body, actionId=action_id))
    assert r.status_code == 400 and field_of(r) == "image.data", r.text

    def chunk(kind, payload):
        return (struct.pack(">I", len(payload)) + kind + payload +
                struct.pack(">I", zlib.crc32(kind + payload)))
    zeros = zlib.compress(b"\x00" * 7_000_000, 9)
    text = b"".join(chunk(b"zTXt", b"k%d\x00\x00" % i + zeros) for i in range(300))
    png = flat_png(16, 16)
    noisy = png[:33] + text + png[33:]
    sid = create(url, rec, target=photos(noisy))
    assert http("GET", f"{url}/v1/sessions/{sid}", rec).status_code == 200
    used = cpu_seconds(pid) - before
    assert used < 3.0, f"{used:.1f} s of CPU"
    rec.check()


def test_a_second_server_cannot_take_the_port(tmp_path):
    """httplib bound with SO_REUSEPORT alone: a second server on the same port (an overlapping
    restart, two replicas, or any process of the same user) started without an error and took
    about half of the connections (21 of 40 GETs of a session answered 404). Now it cannot bind
    and says so; after the first one stops, a new one binds the port at once although the old
    connections linger in TIME_WAIT."""
    first = ServerProcess("--state-dir", str(tmp_path / "a"))
    url, rec = first.url, Recorder()
    try:
        sid = create(url, rec)
        second = subprocess.run([SERVER_BIN, "--port", str(first.port), "--log-level", "warn",
                                 "--state-dir", str(tmp_path / "b")],
                                capture_output=True, text=True, timeout=60)
        assert second.returncode != 0, "a second server started on the same port"
        assert f"cannot bind 127.0.0.1:{first.port}" in second.stderr, second.stderr[-500:]
        for _ in range(20):  # each on a connection of its own, which the server closes
            r = http("GET", f"{url}/v1/sessions/{sid}", rec, headers={"Connection": "close"})
            assert r.status_code == 200
    except BaseException:
        first.kill()
        raise
    assert_clean_exit(first)
    again = subprocess.Popen([SERVER_BIN, "--port", str(first.port), "--log-level", "warn",
                              "--state-dir", str(tmp_path / "a")],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = again.stdout.readline()
        assert line.startswith("listening on"), (line, again.stderr.read() if again.poll() else "")
        assert http("GET", f"{url}/v1/sessions/{sid}", rec).status_code == 200  # restored
    finally:
        again.terminate()
        assert again.wait(timeout=30) == 0
    rec.check()


def test_a_plan_takes_a_planning_slot_per_search_thread(hostile_server):
    """Slots are one per core (2 here): a kct plan on 4 search threads held one slot and kept 4
    cores busy (0.18 s of CPU in 0.11 s with a 50 ms cpuMs budget). It now takes every slot it
    can, and a plan of another session waits for them."""
    url, rec = hostile_server.url, Recorder()
    wide = create(url, rec, planner={"name": "kct", "options": {"search.threads": 4}})
    narrow = create(url, rec)
    done = {}

    def plan(sid, key, ms):
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"timeMs": ms}})
        done[key] = (r.status_code, time.monotonic())

    wide_plan = threading.Thread(target=plan, args=(wide, "wide", 1500))
    wide_plan.start()
    busy = 0
    for _ in range(100):
        metrics = http("GET", f"{url}/metrics", rec).text
        busy = int(next(line.split()[1] for line in metrics.splitlines()
                        if line.startswith("npfkct_planning_slots_busy")))
        if busy:
            break
        time.sleep(0.01)
    assert busy == 2, busy
    started = time.monotonic()
    plan(narrow, "narrow", 50)
    wide_plan.join()
    assert done["wide"][0] == 200 and done["narrow"][0] == 200, done
    assert done["narrow"][1] >= done["wide"][1] - 0.05, "the narrow plan did not wait"
    assert done["narrow"][1] - started > 0.5
    rec.check()


def test_plans_whose_save_failed_still_count_against_the_session(tmp_path):
    """A full disk (here the process's file size limit, SIGXFSZ ignored, so that writes past it
    fail with EFBIG as on a full file system): a plan whose snapshot cannot be written answers
    503 and the session goes back to its last snapshot, which had not counted the plan's CPU,
    so plans on a failing store never used up --max-session-plan-seconds. Now the reloaded
    session keeps what its copy spent, and a 0.4 s plan past a 1 s budget is refused (the second,
    third or fourth: the time counted is the plans' wall-clock time, longer on a loaded machine)."""
    def create_in(server):
        r = http("POST", server.url + "/v1/sessions", None,
                 json={"world": world_of("loose1"), "seed": 3, "planner": {"name": "kct"}})
        assert r.status_code == 200, r.text
        return r.json()["id"]

    probe = ServerProcess("--state-dir", str(tmp_path / "probe"))
    size = os.path.getsize(tmp_path / "probe" / f"{create_in(probe)}.snap")
    assert_clean_exit(probe)

    def disk_full_after_create():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (size + 200, size + 200))  # a plan adds ~780

    server = ServerProcess("--state-dir", str(tmp_path / "state"), "--max-session-plan-seconds",
                           "1", preexec_fn=disk_full_after_create)
    url, rec = server.url, Recorder()
    sid = create_in(server)
    codes = []
    for _ in range(6):
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"cpuMs": 400}})
        codes.append(r.status_code)
        if r.status_code != 503:
            break
    # Without the fix every plan answered 503 (the budget never ran out). How many plans fit in
    # the 1 s depends on the machine's load (the time counted is wall-clock time): at least one
    # plan's save failed, and a later plan was refused for the spent budget.
    assert len(codes) >= 2 and codes[-1] == 429 and set(codes[:-1]) == {503}, codes
    assert field_of(r) == "budget", r.text
    assert "Retry-After" not in r.headers, r.headers  # no retry clears a spent budget
    # The server refuses a plan once less than 10 ms of the budget is left (Session::ClaimForPlan)
    # and grants the last plan only what is left, so what was used is at least 0.99 s, and whether
    # it reaches 1.0 depends on how far that plan overran its clock.
    used = http("GET", f"{url}/v1/sessions/{sid}", rec).json()["planningSecondsUsed"]
    assert used > 0.99, used
    assert_clean_exit(server)


# ---- 2. grid and map overflows ----

def test_worlds_whose_cells_overflow_are_refused_before_allocation(tmp_path):
    state = str(tmp_path / "state")
    server = ServerProcess("--state-dir", state)
    url, rec = server.url, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    base = world_of("loose1")
    cases = []
    w = dict(base, furniture=[{"name": f"w{i}", "center": [0, 0], "size": [19.9, 19.9, 1],
                               "workspace": True} for i in range(4300)])
    cases.append((w, "world.furniture"))  # ~4,300 large workspace pieces
    w = dict(base, furniture=[{"name": f"w{i}", "center": [0, 0], "size": [20, 20, 1],
                               "workspace": True} for i in range(100)])
    cases.append((w, "world.furniture[0].size"))  # 100 workspaces: 1e8 cells of 2 cm
    cases.append((dict(base, room={"min": [-100, -100], "max": [100, 100]}),
                  "world.mapResolution"))  # a 200 m room at 5 cm: 16e6 cells
    cases.append((dict(base, room={"min": [-1e4, -1e4], "max": [1e4, 1e4]}, mapResolution=0.01),
                  "world.mapResolution"))  # 4e12 cells: a 32-bit count would wrap
    for world, field in cases:
        r = http("POST", url + "/v1/sessions", rec, json={"world": world}, timeout=120)
        assert r.status_code == 400, r.text[:300]
        assert field_of(r) == field, r.text[:300]
    # Nothing of them was stored: the server restarts clean, the keeper restored.
    server.kill()
    server = ServerProcess("--state-dir", state)
    rec.add(http("GET", server.url + "/healthz").status_code)
    assert [s["id"] for s in http("GET", server.url + "/v1/sessions").json()["sessions"]] == [keeper]
    assert http("GET", f"{server.url}/v1/sessions/{keeper}/belief").json() == before[keeper][1]
    assert_alive_and_intact(server, {}, rec)
    assert_clean_exit(server)


# ---- 3. bodies: chunked, no length, compressed, ranges ----

def test_bodies_past_the_limit_in_any_framing_and_ranges(hostile_server):
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    # Chunked: 2 GiB announced in 1 MiB chunks; refused (413) once 4 MiB have been counted.
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(b"POST /v1/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n")
        chunk = b"100000\r\n" + b" " * 0x100000 + b"\r\n"
        sent, reply = 0, b""
        try:
            for _ in range(2048):
                s.sendall(chunk)
                sent += 1
                if select.select([s], [], [], 0)[0]:  # the answer came while still sending
                    reply = s.recv(65536)
                    break
        except OSError:
            pass  # the server closed the connection after its 413
        if not reply:
            reply = s.recv(65536)
    assert status_of(reply) == 413, reply[:200]
    assert sent < 64, f"{sent} MiB were accepted before the refusal"
    rec.add(413)
    # Content-Length past the limit: refused before a byte of the body is read.
    reply = raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\nContent-Length: 2147483648\r\n\r\n")
    assert status_of(reply) == 413
    # gzip: 1 MB inflating to 1 GB is never inflated.
    bomb = zlib.compressobj(6, zlib.DEFLATED, 31)
    spaces = b" " * (1 << 20)
    gz = bomb.compress(b"{") + b"".join(bomb.compress(spaces) for _ in range(1024)) + bomb.flush()
    assert len(gz) < 2 << 20
    reply = raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\nContent-Encoding: gzip\r\n"
                         b"Content-Length: %d\r\n\r\n" % len(gz) + gz)
    assert status_of(reply) == 415, reply[:200]
    assert b"X-Content-Type-Options: nosniff" in reply  # the front's own answers too
    # Every Content-Encoding header counts, not the last (httplib inflates by the first): a
    # valid create compressed, then an empty or identity header, was inflated and answered 200.
    small = zlib.compressobj(6, zlib.DEFLATED, 31)
    body = json.dumps({"world": world_of("loose1"), "seed": 1,
                       "planner": {"name": "kct", "particles": 50}}).encode()
    gz = small.compress(body) + small.flush()
    for heads in [[b"gzip", b""], [b"gzip", b"identity"], [b"identity", b"gzip"],
                  [b"identity, gzip"], [b"deflate", b"identity"]]:
        head = b"".join(b"Content-Encoding: " + h + b"\r\n" for h in heads)
        reply = raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\n" + head +
                             b"Content-Length: %d\r\n\r\n" % len(gz) + gz)
        assert status_of(reply) == 415, (heads, reply[:300])
    reply = raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\nContent-Encoding: identity\r\n"
                         b"Content-Encoding:\r\nContent-Length: 2\r\n\r\n{}")
    assert status_of(reply) == 400, reply[:300]  # read as is: an empty create names its field
    # No length, no chunking: no body (answered at once, not read until the client closes).
    t = time.monotonic()
    reply = raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n{\"world\": 1}")
    assert status_of(reply) == 400 and time.monotonic() - t < 5.0
    assert b"expected a JSON object" in reply
    # Both lengths (request smuggling) and other transfer codings.
    for head in [b"Content-Length: 5\r\nTransfer-Encoding: chunked\r\n",
                 b"Transfer-Encoding: gzip, chunked\r\n", b"Content-Length: -1\r\n",
                 b"Content-Length: 5\r\nContent-Length: 6\r\n"]:
        assert status_of(raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\n" + head + b"\r\n")) \
            == 400, head
    # Multi-range requests on the belief: refused, not answered with N copies of it.
    ranges = ",".join(f"0-{i}" for i in range(1000))
    r = http("GET", f"{url}/v1/sessions/{keeper}/belief", rec, headers={"Range": "bytes=" + ranges})
    assert r.status_code == 416 and len(r.content) < 4096
    r = http("GET", f"{url}/v1/sessions/{keeper}/belief?format=png", rec,
             headers={"Range": "bytes=0-1,2-3"})
    assert r.status_code == 416
    for code, _ in rec.codes:
        assert code < 500
    assert_alive_and_intact(hostile_server, before, rec)


def test_heads_httplib_would_read_otherwise_and_connection_tokens(hostile_server):
    # The front frames a request by CRLF lines; httplib also ends a line at a bare LF, so a head
    # with a bare LF, CR or NUL would be two different requests to the two parsers.
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    refused = {
        b"Host: x\nContent-Length: 5\r\n": b"outside a CRLF",
        b"Host: x\rContent-Length: 5\r\n": b"outside a CRLF",
        b"X-A: a\x00b\r\n": b"NUL",
        b"Content-Length 5\r\n": b"without a colon",
        b"Content-Length : 5\r\n": b"not a token",
        b"X-A: a\r\n b\r\n": b"folding",
    }
    for head, why in refused.items():
        reply = raw_exchange(port, b"POST /v1/sessions HTTP/1.1\r\n" + head + b"\r\nhello")
        assert status_of(reply) == 400 and why in reply, (head, reply[:300])
        rec.add(400)
    # A header line httplib would not read (over 8 KiB) in a head within its 16 KiB: 431, as the
    # head limit, not httplib's 400.
    reply = raw_exchange(port, b"GET /healthz HTTP/1.1\r\nAuthorization: Bearer " + b"k" * 10000
                         + b"\r\n\r\n")
    assert status_of(reply) == 431 and b"8192" in reply, reply[:300]
    rec.add(431)
    # Connection is a case-insensitive token list; HTTP/1.0 closes unless asked to keep alive.
    # The second, pipelined request is never answered and the server closes at once.
    second = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    for first in [b"GET /v1/sessions HTTP/1.1\r\nConnection: Close\r\n\r\n",
                  b"GET /v1/sessions HTTP/1.1\r\nConnection: keep-alive, close\r\n\r\n",
                  b"GET /v1/sessions HTTP/1.0\r\n\r\n"]:
        t = time.monotonic()
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(first + second)
            out = b""
            while chunk := s.recv(65536):
                out += chunk
        assert time.monotonic() - t < 5.0, first
        assert out.count(b"HTTP/1.1 ") == 1 and b"Connection: close" in out, (first, out)
        assert b"Keep-Alive" not in out, out
        rec.add(200)
    # Empty lines before a request line are ignored (RFC 9112 2.2).
    reply = raw_exchange(port, b"\r\n\r\nGET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    assert status_of(reply) == 200, reply[:200]
    rec.add(200)
    # An unknown key of 1 MiB is named, cut, in a short answer (not echoed back twice).
    r = http("POST", f"{url}/v1/sessions", rec, json={"k" * (1 << 20): 1})
    assert r.status_code == 400 and len(r.content) < 1024, len(r.content)
    assert field_of(r) == "k" * 96 + "..."
    assert_alive_and_intact(hostile_server, before, rec)


def replies_of(port, data, timeout=10.0):
    """Every response to `data` on one connection until the server closes it: [(status, body)]."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        out = b""
        try:
            while chunk := s.recv(65536):
                out += chunk
        except socket.timeout:
            pass
    replies = []
    while out:
        head, _, rest = out.partition(b"\r\n\r\n")
        length = next((int(l.split(b":")[1]) for l in head.split(b"\r\n")
                       if l.lower().startswith(b"content-length:")), 0)
        replies.append((status_of(head), rest[:length]))
        out = rest[length:]
    return replies


def test_each_request_is_read_once_however_it_is_spelled(hostile_server):
    # The front reads each request once, into the request the routes get: whatever its spelling,
    # a head is framed one way only, or refused and the connection closed.
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    host = b"Host: 127.0.0.1\r\n"
    health = b"GET /healthz HTTP/1.1\r\n" + host + b"Connection: close\r\n\r\n"
    # Pipelined: a chunked body with a chunk extension, a body that holds a request (never
    # answered: it is the body), and the next request; each answered in order, nothing else.
    smuggled = b"GET /nope HTTP/1.1\r\n\r\n"
    replies = replies_of(port, b"POST /v1/sessions HTTP/1.1\r\n" + host +
                         b"Transfer-Encoding: Chunked\r\n\r\n3;ext=1\r\n{x}\r\n0\r\n\r\n"
                         b"GET /v1/sessions HTTP/1.1\r\n" + host +
                         b"Content-Length: %d\r\n\r\n" % len(smuggled) + smuggled + health)
    assert [code for code, _ in replies] == [400, 200, 200], replies
    assert b"SERVING" in replies[2][1] and keeper.encode() in replies[1][1], replies
    # Equal Content-Length lines are one length: the next request is framed after it.
    replies = replies_of(port, b"POST /v1/sessions HTTP/1.1\r\n" + host +
                         b"Content-Length: 2\r\nContent-Length: 2\r\n\r\n{}" + health)
    assert [code for code, _ in replies] == [400, 200], replies
    # HTTP/1.0 kept alive when asked, then the next request.
    replies = replies_of(port, b"GET /healthz HTTP/1.0\r\nConnection: Keep-Alive\r\n\r\n" +
                         health)
    assert [code for code, _ in replies] == [200, 200], replies
    # Refused, the connection closed: a second request after them is never answered.
    refused = {
        b"POST /v1/sessions HTTP/1.1\r\nContent-Length: 2, 2\r\n\r\n{}": b"Content-Length",
        b"POST /v1/sessions HTTP/1.1\r\nContent-Length: +2\r\n\r\n{}": b"Content-Length",
        b"POST /v1/sessions HTTP/1.1\r\nContent-Length: 2\r\nContent-Length: 02\r\n\r\n{}":
            b"conflicting",
        b"POST /v1/sessions HTTP/1.1\r\nTransfer-Encoding: chunked\r\n"
        b"Transfer-Encoding: chunked\r\n\r\n0\r\n\r\n": b"chunked",
        b"GET /healthz HTTP/1.1\r\nX-A: a\r\n\tb\r\n\r\n": b"folding",
        b"GET /healthz HTTP/1.1\r\nX\x00A: b\r\n\r\n": b"NUL",
        b"\nGET /healthz HTTP/1.1\r\n\r\n": b"outside a CRLF",
        b"GET http://127.0.0.1/healthz HTTP/1.1\r\n\r\n": b"starting with '/'",
        b"OPTIONS * HTTP/1.1\r\n\r\n": b"starting with '/'",
        b"CONNECT 127.0.0.1:80 HTTP/1.1\r\n\r\n": b"starting with '/'",
        b"GET /healthz HTTP/1.1\r\n" + b"".join(b"X%d: 1\r\n" % i for i in range(2000)) +
        b"\r\n": b"16384",
        b"POST /v1/sessions HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n0x2\r\n{}\r\n0\r\n"
        b"\r\n": b"chunk size",
    }
    for data, why in refused.items():
        replies = replies_of(port, data + health)
        assert len(replies) == 1 and replies[0][0] in (400, 431), (data[:80], replies)
        assert why in replies[0][1], (data[:80], replies)
        rec.add(replies[0][0])
    # Many tiny header lines within the head's limit, and bytes no parser should choke on.
    for head in (b"A:\r\n" * 3000, b"X-A: \xff\xfe\x01\x7f\r\n"):
        replies = replies_of(port, b"GET /healthz HTTP/1.1\r\n" + host + head +
                             b"Connection: close\r\n\r\n")
        assert [code for code, _ in replies] == [200], replies
    # A second '?' in the target: refused, as always; the connection stays usable.
    replies = replies_of(port, b"GET /v1/sessions?a=1?b=2 HTTP/1.1\r\n" + host + b"\r\n" + health)
    assert [code for code, _ in replies] == [400, 200], replies
    assert_alive_and_intact(hostile_server, before, rec)


# ---- 4. slowloris and starvation ----

def test_slow_and_idle_clients_and_busy_planners_never_delay_health(hostile_server):
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    sessions = [create(url, rec) for _ in range(6)]
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    stop = threading.Event()
    sockets = []
    # 150 slowloris clients (a head byte at a time), 50 idle keep-alive connections, 10 slow
    # bodies, and every planning slot and queue place busy with long plans.
    for _ in range(150):
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(b"GET /v1/sessions HTTP/1.1\r\n")
        sockets.append(s)
    for _ in range(50):
        sockets.append(socket.create_connection(("127.0.0.1", port)))
    for _ in range(10):
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(b"POST /v1/sessions HTTP/1.1\r\nContent-Length: 1000000\r\n\r\n{")
        sockets.append(s)

    def trickle():
        while not stop.is_set():
            for s in sockets[:150] + sockets[200:]:
                try:
                    s.sendall(b"X")
                except OSError:
                    pass
            time.sleep(0.2)

    def plan(sid):
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"timeMs": 2500}},
                 timeout=120)
        return r.status_code

    threading.Thread(target=trickle, daemon=True).start()
    with concurrent.futures.ThreadPoolExecutor(max_workers=8) as pool:
        plans = [pool.submit(plan, sid) for sid in sessions]
        worst = 0.0
        deadline = time.monotonic() + 4.0
        while time.monotonic() < deadline:
            for path in ("/healthz", "/metrics"):
                t = time.monotonic()
                assert http("GET", url + path, rec, timeout=5).status_code == 200
                worst = max(worst, time.monotonic() - t)
            time.sleep(0.05)
        codes = [p.result() for p in plans]
    stop.set()
    for s in sockets:
        s.close()
    assert worst < HEALTH_BOUND, f"/healthz took {worst * 1000:.0f} ms"
    # Two slots, four queue places: six plans run or wait, none is a 5xx; beyond: 429.
    assert all(c in (200, 429) for c in codes), codes
    assert codes.count(200) >= 2
    assert_alive_and_intact(hostile_server, before, rec)


def test_a_burst_of_connections_fits_the_listen_backlog(hostile_server):
    """A burst of connects while the accept loop cannot run (here: the process is stopped) must
    complete in the kernel. With httplib's default backlog of 5 the seventh SYN was dropped and
    its client waited for the 1 s retransmission: a /healthz beside six plan requests took 1 s."""
    url, port = hostile_server.url, hostile_server.port
    burst = 64
    sockets = []
    hostile_server.proc.send_signal(signal.SIGSTOP)
    try:
        for _ in range(burst):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.setblocking(False)
            s.connect_ex(("127.0.0.1", port))
            sockets.append(s)
        deadline = time.monotonic() + 0.5
        pending = list(sockets)
        while pending and time.monotonic() < deadline:
            _, writable, _ = select.select([], pending, [], 0.05)
            pending = [s for s in pending if s not in writable]
        connected = sum(1 for s in sockets if s.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR) == 0
                        and s not in pending)
    finally:
        hostile_server.proc.send_signal(signal.SIGCONT)
        for s in sockets:
            s.close()
    assert connected == burst, f"only {connected} of {burst} connects completed"
    assert http("GET", url + "/healthz", timeout=5).status_code == 200


# ---- 5. memory bombs under an address-space cap ----

def _cap_address_space():
    limit = 2 << 30
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def test_memory_bombs_under_a_2_gib_address_space_cap(tmp_path):
    server = ServerProcess("--max-body-mb", "32", "--max-inflight-mb", "96", "--plan-slots", "2",
                           binary=RELEASE_BIN, preexec_fn=_cap_address_space)
    url, rec = server.url, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    base = world_of("loose1")
    bombs = [
        ({"world": base, "planner": {"name": "kct", "options": {"numCandidates": 1e9}}},
         "planner.options.numCandidates"),
        ({"world": base, "planner": {"name": "kct", "particles": 1000000000}}, "planner.particles"),
        ({"world": base, "planner": {"name": "kct", "options": {"search.numParticles": 1e8}}},
         "planner.options.search.numParticles"),
        ({"world": base, "planner": {"name": "npfkct", "model": "filter.pt",
                                     "options": {"filter.candidates": 1e8}}},
         "planner.options.filter.candidates"),
        ({"world": dict(base, furniture=[{"name": f"w{i}", "center": [0, 0], "size": [20, 20, 1],
                                          "workspace": True} for i in range(100)])},
         "world.furniture[0].size"),
        ({"world": base, "target": {"photos": [base64.b64encode(
            png_header_bomb(19600, 19600)).decode()]}}, "target.photos[0]"),  # 1.15 GB decoded
    ]
    for body, field in bombs:
        r = http("POST", url + "/v1/sessions", rec, json=body)
        assert r.status_code == 400 and field_of(r) == field, r.text[:300]
    # Ten 5 m x 5 m x 3 m blocks are a legal world, but perception cannot map them (34 million
    # surface points around one view): a raw observation is refused before any map is built.
    # (A 200 m room was refused so before perception mapped only around the views: 5.8 GB once.)
    dense = dict(base, furniture=base["furniture"] + [
        {"name": f"block{i}", "center": [20.0 + 6 * i, 20.0], "size": [5, 5, 3], "workspace": False}
        for i in range(10)], room={"min": [-10, -10], "max": [90, 30]}, mapResolution=0.2)
    dense_id = http("POST", url + "/v1/sessions", rec, json={"world": dense, "seed": 2}).json()["id"]
    dense_plan = http("POST", f"{url}/v1/sessions/{dense_id}:plan", rec,
                      json={"budget": {"simulations": 20}}).json()
    r = http("POST", f"{url}/v1/sessions/{dense_id}:observe", rec,
             json=raw_observation(dense_plan["actionId"],
                                  [(0.0, 0.0, 1.0 + 0.001 * i) for i in range(50)]))
    assert r.status_code == 400 and field_of(r) == "pointCloud", r.text
    # A 200 m room at 20 cm is mapped around the views: the frames below are served in it.
    big_room = dict(base, room={"min": [-100, -100], "max": [100, 100]}, mapResolution=0.2)
    sid = http("POST", url + "/v1/sessions", rec, json={"world": big_room, "seed": 2}).json()["id"]
    plan = http("POST", f"{url}/v1/sessions/{sid}:plan", rec,
                json={"budget": {"simulations": 20}}).json()
    # A camera image bomb behind a valid cloud: refused from the header.
    obs = raw_observation(plan["actionId"], [(0.0, 0.0, 1.0)] * 10)
    obs["image"] = {"encoding": "png", "data": base64.b64encode(png_header_bomb(30000, 30000)).decode()}
    obs["camera"] = {"width": 640, "height": 480}
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=obs)
    assert r.status_code == 400 and field_of(r) == "image.data", r.text
    # Work at the limits is served within the cap: a million points, and parallel bodies of
    # 30 MB each (those past the in-flight budget are refused with 429, none fails to allocate).
    cloud = [(random.uniform(-0.5, 0.5), random.uniform(-0.4, 0.4), random.uniform(0.8, 3.0))
             for _ in range(1000)] * 1000
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec,
             json=raw_observation(plan["actionId"], cloud))
    # Perception processes it (the room mapped around the view) within the 2 GiB cap.
    assert r.status_code == 200, r.text[:300]
    flood = json.dumps({"world": base, "displayName": "x", "pad": " " * (30 << 20)})

    def post_big(_):
        try:
            return requests.post(url + "/v1/sessions", data=flood, timeout=120).status_code
        except requests.exceptions.ConnectionError:
            return 429  # refused while still sending
    with concurrent.futures.ThreadPoolExecutor(max_workers=8) as pool:
        codes = list(pool.map(post_big, range(8)))
    for c in codes:
        rec.add(c, "flood")
    assert set(codes) <= {400, 429}, codes
    sessions = [create(url, rec) for _ in range(20)]
    for s in sessions:
        http("POST", f"{url}/v1/sessions/{s}:plan", rec, json={"budget": {"timeMs": 50}})
    log = "".join(server.output)
    assert "bad_alloc" not in log and "out of memory" not in log.lower(), log[-2000:]
    assert all(c != 429 or w == "flood" for c, w in rec.codes)
    assert_alive_and_intact(server, before, rec)
    assert_clean_exit(server)


# ---- 6. DELETE racing plans and observes, then a restart ----

def test_deletes_racing_plans_and_observes_never_come_back_after_a_restart(tmp_path):
    state = str(tmp_path / "state")
    server = ServerProcess("--state-dir", state, "--plan-slots", "4", "--plan-queue", "64",
                           "--max-sessions", "40")
    url, rec = server.url, Recorder()
    keepers = [create(url, rec) for _ in range(3)]
    before = {k: snapshot_of(url, k) for k in keepers}
    deleted = []

    def race(i):
        rnd = random.Random(i)
        sid = create(url, rec)
        if i % 2 == 0:
            plan = http("POST", f"{url}/v1/sessions/{sid}:plan", rec,
                        json={"budget": {"simulations": 30}}).json()
            racer = lambda: http("POST", f"{url}/v1/sessions/{sid}:observe", rec,  # noqa: E731
                                 json=observation(plan["actionId"]))
        else:
            racer = lambda: http("POST", f"{url}/v1/sessions/{sid}:plan", rec,  # noqa: E731
                                 json={"budget": {"timeMs": rnd.choice([5, 20, 60])}})
        with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
            f = pool.submit(racer)
            time.sleep(rnd.uniform(0.0, 0.03))
            d = http("DELETE", f"{url}/v1/sessions/{sid}", rec)
            assert d.status_code == 200, d.text
            r = f.result()
        assert r.status_code in (200, 404, 409), r.text
        return sid

    with concurrent.futures.ThreadPoolExecutor(max_workers=6) as pool:
        deleted = list(pool.map(race, range(100)))
    # kill -9: no orderly shutdown may tidy anything up.
    server.kill()
    server = ServerProcess("--state-dir", state, "--max-sessions", "40")
    rec.add(http("GET", server.url + "/healthz").status_code)
    alive = {s["id"] for s in http("GET", server.url + "/v1/sessions",
                                   params={"pageSize": 1000}).json()["sessions"]}
    assert alive == set(keepers), f"{len(alive & set(deleted))} deleted sessions came back"
    # Snapshots and the directory's lock only: no temporary file left behind.
    assert not [f for f in os.listdir(state) if not f.endswith(".snap") and f != ".lock"]
    assert_alive_and_intact(server, before, rec)
    assert_clean_exit(server)


# ---- 7. TTL shorter than a plan ----

def test_a_ttl_shorter_than_a_plan(hostile_server):
    url, rec = hostile_server.url, Recorder()
    sid = create(url, rec, ttlSeconds=0.3)
    r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"timeMs": 1500}})
    assert r.status_code == 200, r.text
    assert http("GET", f"{url}/v1/sessions/{sid}", rec).json()["state"] == "ACTION_PENDING"
    time.sleep(1.5)
    assert http("GET", f"{url}/v1/sessions/{sid}", rec).status_code == 404
    rec.check()


# ---- 8. probing the filesystem through planner.model ----

def test_model_names_never_reach_the_filesystem(hostile_server):
    url, rec = hostile_server.url, Recorder()
    base = world_of("loose1")
    answers = set()
    for name in ["/etc/passwd", "../../../../etc/passwd", "filter.pt/../../x", "%2e%2e/x.pt",
                 "x" * 5000, "filter.pt\u0000.txt", "/dev/zero", "/proc/self/environ",
                 "..", ".", " filter.pt", "nonexistent.pt", "/tmp"]:
        r = http("POST", url + "/v1/sessions", rec,
                 json={"world": base, "planner": {"name": "npfkct", "model": name}})
        assert r.status_code == 400 and field_of(r) == "planner.model", (name, r.text)
        answers.add(r.json()["error"]["message"].replace(name, "NAME"))
    # The old path field: unknown; absolute paths in any other field are plain strings.
    r = http("POST", url + "/v1/sessions", rec,
             json={"world": base, "planner": {"modelPath": "/etc/passwd"}})
    assert r.status_code == 400 and field_of(r) == "planner.modelPath"
    # An existing file outside the folder and a missing one get the same answer.
    passwd = http("POST", url + "/v1/sessions", rec,
                  json={"world": base, "planner": {"model": "passwd"}}).json()["error"]["message"]
    missing = http("POST", url + "/v1/sessions", rec,
                   json={"world": base, "planner": {"model": "nosuchfile"}}).json()
    assert passwd.replace("passwd", "N") == missing["error"]["message"].replace("nosuchfile", "N")
    assert http("POST", url + "/v1/sessions", rec,
                json={"world": base, "planner": {"name": "npfkct", "model": "filter.pt"}}
                ).status_code == 200
    # "" names no model: uniform candidates, nothing looked up.
    none = http("POST", url + "/v1/sessions", rec,
                json={"world": base, "planner": {"name": "npfkct", "model": ""}})
    assert none.status_code == 200 and none.json()["planner"]["model"] == "", none.text
    rec.check()


# ---- 9. a hostile state directory ----

def test_hostile_state_directory_entries(tmp_path):
    state = tmp_path / "state"
    server = ServerProcess("--state-dir", str(state))
    url, rec = server.url, Recorder()
    keepers = [create(url, rec) for _ in range(3)]
    before = {k: snapshot_of(url, k) for k in keepers}
    assert_clean_exit(server)
    snaps = sorted(p.name for p in state.iterdir())
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    os.mkfifo(state / ("1" * 32 + ".snap"))
    os.symlink("/etc/passwd", state / ("2" * 32 + ".snap"))
    os.mkdir(state / ("3" * 32 + ".snap"))
    with open(state / ("4" * 32 + ".snap"), "wb") as f:
        f.truncate(10 << 30)  # a sparse 10 GB file
    (state / ("5" * 32 + ".snap")).write_bytes(os.urandom(4096))
    os.symlink(victim, state / ("6" * 32 + ".snap.tmp.00000000deadbeef"))
    (state / "notes.txt").write_text("not a snapshot")
    # A snapshot whose name is not its id, and a checksummed snapshot holding garbage.
    (state / ("7" * 32 + ".snap")).write_bytes((state / snaps[0]).read_bytes())
    payload = b'{"version": 2, "id": "' + b"8" * 32 + b'", "world": {"grid": 5}}'
    (state / ("8" * 32 + ".snap")).write_bytes(
        b"npfkct-snapshot 2 1 %d %08x\n" % (len(payload), zlib.crc32(payload)) + payload)
    t = time.monotonic()
    server = ServerProcess("--state-dir", str(state), "--max-sessions", "2")
    assert time.monotonic() - t < 10.0
    restored = {s["id"] for s in http("GET", server.url + "/v1/sessions", rec).json()["sessions"]}
    assert len(restored) == 2 and restored <= set(keepers)  # --max-sessions holds at restore
    assert victim.read_text() == "keep me"
    assert not os.path.lexists(state / ("6" * 32 + ".snap.tmp.00000000deadbeef"))
    for sid in restored:
        assert snapshot_of(server.url, sid) == before[sid]
    # The server is full (2 of 2): creation is refused with 429, not a crash or an overflow.
    r = http("POST", server.url + "/v1/sessions", rec, json={"world": world_of("loose1")})
    assert r.status_code == 429 and r.headers.get("Retry-After")
    assert_clean_exit(server)
    server = ServerProcess("--state-dir", str(state))
    assert {s["id"] for s in http("GET", server.url + "/v1/sessions", rec).json()["sessions"]} \
        == set(keepers)
    assert_alive_and_intact(server, before, rec)
    assert_clean_exit(server)


# ---- 10. everything at once: random hostile traffic, then the survivors ----

def test_mixed_hostile_traffic_leaves_other_sessions_intact(hostile_server):
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    keepers = [create(url, rec) for _ in range(3)]
    before = {k: snapshot_of(url, k) for k in keepers}
    victims = [create(url, rec) for _ in range(3)]
    rnd = random.Random(7)
    bodies = [b"{", b"[]", b"null", b'{"budget": {"timeMs": 1e400}}', b"[" * 100000,
              b'{"budget": {"simulations": 1.5}}', b"\xff\xfe\x00", b'{"a":' * 70 + b"1" + b"}" * 70,
              json.dumps({"actionId": "a", "detections": [{"id": str(i), "box": {
                  "center": [0, 0, 0], "size": [1, 1, 1]}} for i in range(64)]}).encode()]

    def one(i):
        r = random.Random(i)
        sid = r.choice(victims + ["0" * 32, "../etc", "x" * 2000])
        kind = r.randrange(4)
        try:
            if kind == 0:
                resp = requests.post(f"{url}/v1/sessions/{sid}:plan", data=r.choice(bodies),
                                     timeout=60)
            elif kind == 1:
                resp = requests.post(f"{url}/v1/sessions/{sid}:observe", data=r.choice(bodies),
                                     timeout=60)
            elif kind == 2:
                resp = requests.post(f"{url}/v1/sessions", data=r.choice(bodies), timeout=60)
            else:
                resp = requests.get(f"{url}/v1/sessions/{sid}/belief", timeout=60,
                                    headers={"Range": "bytes=0-1,3-4"})
            rec.add(resp.status_code, f"{kind} {sid[:40]}")
        except requests.exceptions.ConnectionError:
            rec.add(-1, "connection error")
    with concurrent.futures.ThreadPoolExecutor(max_workers=12) as pool:
        list(pool.map(one, range(600)))
    for raw in [b"GET / HTTP/1.1\r\n\r\n", b"\x00\x01\x02garbage\r\n\r\n",
                b"GET /" + b"a" * 20000 + b" HTTP/1.1\r\n\r\n",
                b"GET /healthz HTTP/1.1\r\n" + b"X-A: b\r\n" * 5000 + b"\r\n",
                b"POST /v1/sessions HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n"]:
        reply = raw_exchange(port, raw, timeout=5, shutdown=True)
        code = status_of(reply)
        assert code is None or code < 500, reply[:200]
    assert -1 not in [c for c, _ in rec.codes]
    del rnd
    assert_alive_and_intact(hostile_server, before, rec)


# ---- found by an outside-style attack pass (session 15) ----

def test_multipart_bodies_odd_methods_and_option_spellings(hostile_server):
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    keeper = create(url, rec)
    before = {keeper: snapshot_of(url, keeper)}
    # A multipart body: httplib's plain body reader throws on one (a 500 before this fix).
    part = b"--xx\r\nContent-Disposition: form-data; name=\"a\"\r\n\r\n1\r\n--xx--\r\n"
    for target in (b"/v1/sessions", b"/v1/sessions/" + keeper.encode() + b":plan"):
        reply = raw_exchange(port, b"POST " + target + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                             b"Content-Type: multipart/form-data; boundary=xx\r\n"
                             b"Content-Length: " + str(len(part)).encode() + b"\r\n\r\n" + part)
        assert status_of(reply) == 415, reply[:300]
        rec.add(415)
    # A method that is not HTTP's: counted as "other", never copied into /metrics; one that is
    # not even a token is a malformed request line.
    reply = raw_exchange(port, b'A"},evil="1 /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n')
    assert status_of(reply) == 400 and b"malformed request line" in reply, reply[:200]
    reply = raw_exchange(port, b"evil /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    assert status_of(reply) in (400, 404, 405, 501), reply[:200]
    metrics = http("GET", url + "/metrics", rec).text
    assert "evil" not in metrics
    assert 'method="other"' in metrics
    # Option keys reach the planner in snake_case: other spellings of a bounded option would
    # pass its bound, so only lowerCamelCase keys are taken.
    for key in ("num_candidates", "search.Threads", "K", "diameter_samples", "search.num_particles"):
        r = http("POST", url + "/v1/sessions", rec,
                 json={"world": world_of("loose1"), "planner": {"name": "kct",
                                                                "options": {key: 1e9}}})
        assert r.status_code == 400, (key, r.text)
        assert field_of(r) == "planner.options." + key, r.text
    assert_alive_and_intact(hostile_server, before, rec)


def sparse_world():
    """A world at its limits: a 20 x 20 m room at 2 cm (1M map cells), 100 small tables and 64
    small base regions, so that aiming a view takes many tries."""
    world = world_of("loose1")
    world["room"] = {"min": [-10, -10], "max": [10, 10]}
    world["mapResolution"] = 0.02
    world["furniture"] = [{"name": f"f{i}", "center": [-9 + 2 * (i % 10), -9 + 2 * (i // 10)],
                           "size": [0.99, 0.99, 0.75], "workspace": True} for i in range(100)]
    world["baseRegions"] = [{"min": [-9.9 + 2.4 * (i % 8), -9.9 + 2.4 * (i // 8)],
                             "max": [-9.4 + 2.4 * (i % 8), -9.4 + 2.4 * (i // 8)]}
                            for i in range(64)]
    world["start"] = {"x": 0.0, "y": 0.0, "yaw": 0.0, "lift": 0.2, "pan": 0.0, "tilt": 0.3}
    world.pop("discretePoses", None)
    return world


def test_belief_pictures_are_admitted_like_plans(hostile_server):
    # A picture of a large world takes up to half a second of CPU; 40 at once used to occupy the
    # request threads, and a session list waited seconds behind them. Now they take planning
    # slots (2 here, 4 waiting): the rest get 429 with Retry-After and other requests go on.
    url, rec = hostile_server.url, Recorder()
    sid = create(url, rec, world=sparse_world())
    codes, lists = [], []

    def picture():
        r = http("GET", f"{url}/v1/sessions/{sid}/belief?format=png", rec)
        codes.append((r.status_code, r.headers.get("Retry-After")))

    pictures = [threading.Thread(target=picture) for _ in range(40)]
    for t in pictures:
        t.start()
    for _ in range(5):
        t = time.monotonic()
        assert http("GET", f"{url}/v1/sessions", rec).status_code == 200
        lists.append(time.monotonic() - t)
    for t in pictures:
        t.join()
    assert sorted(set(codes)) == [(200, None), (429, "1")], codes
    assert sum(code == 200 for code, _ in codes) >= 6, codes
    assert max(lists) < 1.0, lists
    rec.check()


def test_work_inside_a_simulation_or_before_it_stops_with_the_plan(hostile_server):
    # A sparse world at its limits (1M map cells, 100 small tables, 64 small base regions) and the
    # options at their caps. Before every part polled the plan's condition: npfkct's candidate
    # sampling (100,000 filter candidates) took 13 s whatever the budget, kct's clustering of
    # 8,192 candidates made a 300 ms plan 0.85 s, and advt's cell splits (64 per visit, each up to
    # 10,000 walks of 10,000 steps) ran a 50 ms plan for minutes; none stopped at a DELETE.
    # pomcpow and vomcpow, whose new actions draw feasible points, are held to the same.
    url, rec = hostile_server.url, Recorder()
    world = sparse_world()
    caps = {"numCandidates": 4096, "maxInitialClusters": 16, "k": 16}
    filter_caps = dict(caps, **{"filter.candidates": 100000, "filter.context": 256,
                                "filter.placements": 4096})
    planners = [
        ("npfkct", 10000, filter_caps, 50),
        # The same with every candidate scored exactly (4,096 placements each) in place of the
        # network.
        ("npfkct", 10000, dict(filter_caps, **{"filter.exact": 1}), 50),
        ("kct", 10000, dict(caps, maxFeasibilityTries=10000, treeFeasibilityTries=1000,
                            **{"search.threads": 4}), 300),
        ("advt", 100, {"walkSteps": 10000, "splitCoefficient": 1000, "feasibilityTries": 10000,
                       "diameterSamples": 300}, 50),
        # Each new action of these takes up to 10,000 feasibility checks or Voronoi proposals.
        ("pomcpow", 10000, {"feasibilityTries": 10000, "voo.maxTries": 10000, "useVoo": True,
                            "search.maxDepth": 100}, 50),
        ("vomcpow", 10000, {"feasibilityTries": 10000, "voo.maxTries": 10000,
                            "search.maxDepth": 100}, 50),
    ]
    for name, particles, options, budget_ms in planners:
        spec = {"name": name, "particles": particles, "options": options}
        sid = create(url, rec, world=world, planner=spec)
        t = time.monotonic()
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec,
                 json={"budget": {"timeMs": budget_ms}})
        took = time.monotonic() - t
        assert r.status_code == 200 and took < budget_ms / 1000 + 1.5, (name, took, r.text[:200])
        # A long plan deleted while it works ends at once.
        sid = create(url, rec, world=world, planner=spec)
        ended = {}

        def plan():
            ended["r"] = http("POST", f"{url}/v1/sessions/{sid}:plan", rec,
                              json={"budget": {"timeMs": 30000}})
            ended["t"] = time.monotonic()

        worker = threading.Thread(target=plan)
        worker.start()
        time.sleep(0.5)
        t = time.monotonic()
        assert http("DELETE", f"{url}/v1/sessions/{sid}", rec).status_code == 200
        worker.join(timeout=30)
        assert ended["t"] - t < 0.5, (name, ended["t"] - t)
        assert ended["r"].status_code == 409, ended["r"].text
    rec.check()


def test_a_growing_search_tree_stops_at_the_heap_bound(tmp_path):
    # pomcp-joint's tree grows by about 400 MiB a second here; with --max-heap-mb 256 a 5 s plan
    # stops early with its best action. The resident peak stays near the bound: the tree's node
    # arrays grow in blocks (they doubled in one piece, and the old and new arrays were both
    # resident while one was copied). The tree that reached the bound is dropped and its memory
    # given back: kept, it refused the session's own observation until a DELETE (and everyone
    # else's plans), and freed trees stayed resident in the arena of the thread that grew them
    # (3 GiB resident after six create-plan-delete cycles at a 1 GiB bound). The Release build:
    # ASan's allocator is not the one the bound reads.
    server = ServerProcess("--state-dir", str(tmp_path / "state"), "--max-heap-mb", "256",
                           binary=RELEASE_BIN)
    url, rec = server.url, Recorder()

    def rss_mib(key="VmRSS"):
        with open(f"/proc/{server.proc.pid}/status") as f:
            return next(int(l.split()[1]) for l in f if l.startswith(key)) / 1024

    start = rss_mib()
    big = create(url, rec, planner={"name": "pomcp-joint"})
    other = create(url, rec)
    pending = planned(url, rec)
    for cycle in range(3):
        t = time.monotonic()
        r = http("POST", f"{url}/v1/sessions/{big}:plan", rec, json={"budget": {"timeMs": 5000}})
        assert r.status_code == 200, r.text
        assert time.monotonic() - t < 4.0
        stats = r.json()["stats"]
        assert stats["budgetExhausted"] is False and stats["simulations"] > 0, stats
        assert rss_mib() - start < 100, (cycle, start, rss_mib())
        assert rss_mib("VmHWM") - start < 256 + 64, (cycle, start, rss_mib("VmHWM"))
        r = http("POST", f"{url}/v1/sessions/{big}:observe", rec,
                 json=observation(r.json()["actionId"]))
        assert r.status_code == 200, r.text
    r = http("POST", f"{url}/v1/sessions/{other}:plan", rec, json={"budget": {"timeMs": 200}})
    assert r.status_code == 200, r.text
    # Sessions of 10,000 particles in a 36 m room, each with the prior map of a frame as wide as
    # registration_range allows (30-110 MB each), hold the heap past the bound (one such map of
    # the whole room did, before perception built its map around the views): nothing that grows
    # the heap starts (plans, observations, new sessions), and each 429 says when to retry (the
    # plan's and the observation's said nothing).
    world = example("create_session_request.json")["world"]
    world["room"] = {"min": [-18, -18], "max": [18, 18]}
    fresh = create(url, rec)
    holders, view = [], three_squares(1.2, -1.2, 1.6) + registration_edge_points()
    for _ in range(12):
        r = http("POST", url + "/v1/sessions", rec,
                 json={"world": world, "seed": 1, "planner": {"name": "kct", "particles": 10000}})
        if r.status_code == 429:
            break
        assert r.status_code == 200, r.text
        holders.append(r.json()["id"])
        action = http("POST", f"{url}/v1/sessions/{holders[-1]}:plan", rec,
                      json={"budget": {"simulations": 20}}).json()["actionId"]
        r = http("POST", f"{url}/v1/sessions/{holders[-1]}:observe", rec,
                 json=raw_observation(action, view, "map"), timeout=120)
        if r.status_code == 429:
            break
        assert r.status_code == 200, r.text
    assert 2 <= len(holders) < 12, len(holders)
    for method, path, body in [("POST", f"/v1/sessions/{fresh}:plan", {"budget": {"timeMs": 200}}),
                               ("POST", f"/v1/sessions/{pending[0]}:observe",
                                observation(pending[1])),
                               ("POST", "/v1/sessions", {"world": world_of("loose1")})]:
        r = http(method, url + path, rec, json=body)
        assert r.status_code == 429 and "max-heap-mb" in r.json()["error"]["message"], r.text
        assert r.headers["Retry-After"] == "5", (path, r.headers)
        assert any(d.get("retryDelay") == "5s" for d in r.json()["error"]["details"]), r.text
    for holder in holders:
        assert http("DELETE", f"{url}/v1/sessions/{holder}", rec).status_code == 200
    r = http("POST", f"{url}/v1/sessions/{fresh}:plan", rec, json={"budget": {"timeMs": 200}})
    assert r.status_code == 200, r.text
    r = http("POST", f"{url}/v1/sessions/{pending[0]}:observe", rec, json=observation(pending[1]))
    assert r.status_code == 200, r.text
    create(url, rec)
    rec.check()
    assert_clean_exit(server)


# ---- session 18: an outside tester's findings ----

def test_base_regions_are_cut_to_the_room_and_must_leave_room_for_the_robot(hostile_server):
    # One base region 20 km wide (within the coordinate limit) made every draw of a base pose
    # fall outside the room: kct's decision then tried the draws of every one of its thousands of
    # root spheres after the budget (a 200 ms plan ran 35 s with maxFeasibilityTries 10,000, past
    # a DELETE and SIGTERM) and answered a MOVE kilometres outside the room.
    url, rec = hostile_server.url, Recorder()
    world = world_of("loose1")
    world["baseRegions"] = [{"min": [-1e4, -1e4], "max": [1e4, 1e4]}]
    for name in ("kct", "npfkct"):
        sid = create(url, rec, world=world,
                     planner={"name": name, "particles": 1000,
                              "options": {"maxFeasibilityTries": 10000}})
        t = time.monotonic()
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"timeMs": 200}})
        took = time.monotonic() - t
        assert r.status_code == 200 and took < 1.5, (name, took, r.text[:300])
        move = r.json()["action"]["configuration"]
        assert -3 <= move["x"] <= 4 and -3 <= move["y"] <= 3.5, (name, move)
    # A region with no part in the room, or regions with no free point for the robot (inside
    # the table), are refused at creation, naming the field.
    for regions, field in [([{"min": [10, 10], "max": [11, 11]}], "world.baseRegions[0]"),
                           (world_of("loose1")["baseRegions"] + [{"min": [-9, 0], "max": [-8, 1]}],
                            "world.baseRegions[4]"),
                           ([{"min": [1.2, -0.2], "max": [2.0, 0.2]}], "world.baseRegions")]:
        bad = dict(world, baseRegions=regions)
        r = http("POST", url + "/v1/sessions", rec, json={"world": bad})
        assert r.status_code == 400 and field_of(r) == field, r.text
    # A block filling the room but for a corner, and a base region in each: the 4,096 draws find
    # the corner, and npfkct's filter kept only proposals inside the block (uniform draws that
    # found no free base were proposed anyway), so its MOVE put the base inside the block.
    world = world_of("loose1")
    world["furniture"].append({"name": "block", "center": [0.9, 0.4], "size": [6.2, 5.8, 0.5]})
    world["baseRegions"] = [{"min": [0.0, 0.0], "max": [4.0, 3.5]},
                            {"min": [-2.64, -2.64], "max": [-2.56, -2.56]}]
    world["start"] = {"x": -2.6, "y": -2.6, "yaw": 0.0, "lift": 0.0, "pan": 0.0, "tilt": 0.0}
    for name in ("npfkct", "kct"):
        sid = create(url, rec, world=world, planner={"name": name, "particles": 300})
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"timeMs": 200}})
        assert r.status_code == 200, r.text
        move = r.json()["action"]["configuration"]
        assert -2.64 <= move["x"] <= -2.56 and -2.64 <= move["y"] <= -2.56, (name, move)
    rec.check()


def test_a_move_keeps_only_joints_the_robot_can_take(hostile_server):
    # A robot state with lift, pan and tilt at +-1000 (inside the API's bound on angles) made
    # pomcp's and gpomcp's base moves ask for the same joints back.
    url, rec = hostile_server.url, Recorder()
    for name in ("pomcp", "gpomcp"):
        sid, action = planned(url, rec, planner={"name": name, "particles": 50})
        body = observation(action)
        body["robotState"].update(lift=-1000, pan=1000, tilt=-1000)
        assert http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=body).status_code == 200
        for _ in range(6):
            r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec,
                     json={"budget": {"simulations": 200}})
            assert r.status_code == 200, r.text
            a = r.json()["action"]
            if a["type"] == "MOVE":
                c = a["configuration"]
                assert 0 <= c["lift"] <= 0.4 and abs(c["pan"]) <= 0.27 and abs(c["tilt"]) <= 0.5, c
            obs = observation(r.json()["actionId"])
            obs["robotState"].update(lift=-1000, pan=1000, tilt=-1000)
            obs["detections"] = []
            if http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=obs).json().get("done"):
                break
    rec.check()


def test_strings_with_nul_pass_no_length_limit(hostile_server):
    # The schema validator measured strings up to their first NUL: "a\u0000" and 25 MiB more
    # passed every maxLength, and a restored session came back with its strings cut.
    url, rec = hostile_server.url, Recorder()
    for key, value, field in [("displayName", "a\u0000" + "x" * 1000, "displayName"),
                              ("target", {"description": "\u0000" * 3000}, "target.description")]:
        r = http("POST", url + "/v1/sessions", rec,
                 json={"world": world_of("loose1"), key: value})
        assert r.status_code == 400 and field_of(r) == field, r.text
    sid, action = planned(url, rec)
    body = observation(action)
    body["detections"][0]["id"] = "b\u0000" + "y" * 1000
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=body)
    assert r.status_code == 400 and field_of(r) == "detections[0].id", r.text
    rec.check()


def test_web_pages_of_other_sites_cannot_use_the_api(tmp_path):
    # Without an API key on loopback, any page the operator opened could POST to the server (a
    # text/plain "simple" request needs no preflight) or, after DNS rebinding, read it.
    server = ServerProcess("--state-dir", str(tmp_path / "state"))
    url, port, rec = server.url, server.port, Recorder()
    body = json.dumps({"world": world_of("loose1")})
    refused = [({"Origin": "http://evil.example", "Content-Type": "text/plain"}, "Origin"),
               ({"Origin": "null"}, "Origin"),
               ({"Sec-Fetch-Site": "cross-site"}, "Sec-Fetch-Site"),
               ({"Host": f"evil.example:{port}"}, "Host")]
    for headers, field in refused:
        r = http("POST", url + "/v1/sessions", rec, data=body, headers=headers)
        assert r.status_code == 403 and field_of(r) == field, (headers, r.text)
        assert r.headers["X-Content-Type-Options"] == "nosniff"
    assert http("GET", url + "/v1/sessions", rec).json()["sessions"] == []
    r = http("GET", url + "/v1/sessions", rec, headers={"Host": "rebound.example"})
    assert r.status_code == 403, r.text
    # The console's own calls (same origin), and clients that are not browsers, go through.
    r = http("POST", url + "/v1/sessions", rec, data=body,
             headers={"Origin": f"http://127.0.0.1:{port}", "Sec-Fetch-Site": "same-origin",
                      "Content-Type": "application/json"})
    assert r.status_code == 200, r.text
    assert http("GET", url + "/ui", rec, headers={"Sec-Fetch-Site": "cross-site"}).ok
    # A method that is not HTTP's is named in the error.
    reply = raw_exchange(port, b"BREW /v1/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    assert status_of(reply) == 400 and b"method BREW is not supported" in reply, reply[:300]
    rec.check()
    assert_clean_exit(server)


def big_belief_world():
    """A world whose belief is about 1.2 MB of JSON: one 9.8 m table of 240,000 grid cells."""
    world = world_of("loose1")
    world["room"] = {"min": [-6, -6], "max": [6, 6]}
    world["furniture"] = [{"name": "table", "center": [0, 0], "size": [9.8, 9.8, 0.75],
                           "workspace": True}]
    world["baseRegions"] = [{"min": [-5.9, -5.9], "max": [-5.0, 5.9]}]
    world.pop("discretePoses", None)
    world["start"] = {"x": -5.5, "y": 0.0, "yaw": 0.0, "lift": 0.2, "pan": 0.0, "tilt": 0.3}
    return world


def test_clients_that_never_read_their_responses_hold_no_request_thread(hostile_server):
    # Each connection pipelines five GETs of a 1.2 MB belief and never reads: the kernel's
    # buffers take about three replies, and the worker writing the fourth waited 10 s for the
    # socket. 16 such connections (about 1 kB sent) held every request thread (10 here) and a
    # session list waited more than 10 s. Replies the socket does not take now wait in the
    # reactor, which sends them as the client reads.
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    sid = create(url, rec, world=big_belief_world())
    one = f"GET /v1/sessions/{sid}/belief HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
    readers = []
    try:
        for _ in range(16):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 2048)
            s.connect(("127.0.0.1", port))
            s.sendall(one * 5)
            readers.append(s)
        # The replies are rendered first (seconds of CPU on the sanitized build): probe once
        # the server is idle, when only the sockets it writes to are left.
        pid, deadline = hostile_server.proc.pid, time.monotonic() + 120
        used = cpu_seconds(pid)
        while time.monotonic() < deadline:
            time.sleep(1.0)
            now = cpu_seconds(pid)
            if now - used < 0.05:
                break
            used = now
        for _ in range(3):
            t = time.monotonic()
            assert http("GET", url + "/v1/sessions", rec).status_code == 200
            assert time.monotonic() - t < 10.0, time.monotonic() - t
        # A reader that reads at last gets all five replies, whole.
        s = readers[0]
        s.settimeout(30)
        data = b""
        while data.count(b"HTTP/1.1 200") < 5 or not data.endswith(b"}"):
            chunk = s.recv(1 << 20)
            assert chunk, "closed early"
            data += chunk
        assert data.count(b"HTTP/1.1 200 OK") == 5
    finally:
        for s in readers:
            s.close()
    rec.check()


def test_replies_sent_as_the_client_reads_arrive_whole_and_in_order(hostile_server):
    # A reply the socket took in part was kept in part, but the write reported the part kept as
    # all it took: httplib then wrote the tail of the body again, and every later reply on the
    # connection was read from the wrong place. One connection pipelines 60 PNG beliefs (about
    # 140 kB each) and reads 64 kB every 30 ms.
    url, port, rec = hostile_server.url, hostile_server.port, Recorder()
    sid = create(url, rec)
    one = f"GET /v1/sessions/{sid}/belief?format=png HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        s.sendall(one.encode() * 60)
        data, replies = b"", []
        while len(replies) < 60:
            time.sleep(0.03)
            chunk = s.recv(65536)
            assert chunk, f"closed after {len(replies)} replies"
            data += chunk
            while b"\r\n\r\n" in data:
                head, _, rest = data.partition(b"\r\n\r\n")
                assert head.startswith(b"HTTP/1.1 200 OK\r\n"), (len(replies), head[:80])
                length = int(next(l.split(b":")[1] for l in head.split(b"\r\n")
                                  if l.lower().startswith(b"content-length:")))
                if len(rest) < length:
                    break
                replies.append(rest[:length])
                data = rest[length:]
        s.settimeout(0.5)
        try:
            data += s.recv(65536)
        except socket.timeout:
            pass
    assert data == b"", f"{len(data)} bytes after the last reply"
    assert all(r.startswith(b"\x89PNG") and r.endswith(b"IEND\xaeB`\x82") for r in replies)
    assert len(set(replies)) == 1  # the same picture each time
    rec.check()


def test_plans_waiting_for_a_slot_are_the_sessions_and_leave_with_it(tmp_path):
    # A plan waited in the planning queue before it claimed its session: a second plan on the
    # same session was queued (holding a queue place) instead of refused at once, the TTL reaped
    # a session whose plan was queued, and a deleted session's plan kept its place until a slot
    # freed.
    server = ServerProcess("--state-dir", str(tmp_path / "state"), "--plan-slots", "1",
                          "--plan-queue", "1", "--session-ttl", "2")
    url, rec = server.url, Recorder()
    busy, waiting = create(url, rec), create(url, rec)
    results = {}

    def plan(name, sid, ms):
        t = time.monotonic()
        r = http("POST", f"{url}/v1/sessions/{sid}:plan", rec, json={"budget": {"timeMs": ms}})
        results[name] = (r, time.monotonic() - t)

    first = threading.Thread(target=plan, args=("busy", busy, 4000))
    first.start()
    time.sleep(0.5)
    queued = threading.Thread(target=plan, args=("waiting", waiting, 200))
    queued.start()
    time.sleep(0.5)
    # The session in the queue answers a second plan at once, without taking the queue place.
    t = time.monotonic()
    r = http("POST", f"{url}/v1/sessions/{waiting}:plan", rec, json={"budget": {"timeMs": 200}})
    # Answered while the 4 s plan still runs: it did not wait for the slot (a causal check, not a
    # time limit a loaded machine could miss).
    assert r.status_code == 409 and "busy" not in results, r.text
    # Past its TTL in the queue (2 s), it is still there: in use, not idle.
    time.sleep(2.5)
    assert http("GET", f"{url}/v1/sessions", rec).json()["sessions"]
    queued.join(timeout=30)
    r, _ = results["waiting"]
    assert r.status_code == 200, r.text
    first.join(timeout=30)
    # A deleted session's queued plan leaves the queue at once.
    first = threading.Thread(target=plan, args=("busy2", create(url, rec), 3000))
    first.start()
    time.sleep(0.5)
    doomed = create(url, rec)
    queued = threading.Thread(target=plan, args=("doomed", doomed, 200))
    queued.start()
    time.sleep(0.5)
    assert http("DELETE", f"{url}/v1/sessions/{doomed}", rec).status_code == 200
    queued.join(timeout=30)
    r, took = results["doomed"]
    # It left the queue while the 3 s plan still held the slot.
    assert r.status_code == 409 and "busy2" not in results, (r.text, took)
    first.join(timeout=30)
    assert results["busy2"][0].status_code == 200, results["busy2"][0].text
    rec.check()
    assert_clean_exit(server)


def test_a_session_whose_snapshot_cannot_be_removed_is_kept(tmp_path):
    # DELETE answered 503 (the snapshot could not be removed) after dropping the session from
    # memory: GET then said 404, and the session came back at the next start. A TTL expiry did
    # the same. The snapshot stands in the way here as a directory of its name.
    state = tmp_path / "state"
    server = ServerProcess("--state-dir", str(state))
    url, rec = server.url, Recorder()
    sid = create(url, rec)
    short = create(url, rec, ttlSeconds=1)
    for s in (sid, short):
        snap = state / f"{s}.snap"
        snap.unlink()
        (snap / "blocker").mkdir(parents=True)
    r = http("DELETE", f"{url}/v1/sessions/{sid}", rec)
    assert r.status_code == 503, r.text
    rec.add(200)  # the 503 is the answer wanted here
    rec.codes = [c for c in rec.codes if c[0] != 503]
    assert http("GET", f"{url}/v1/sessions/{sid}", rec).status_code == 200
    time.sleep(2.5)
    listed = {s["id"] for s in http("GET", f"{url}/v1/sessions", rec).json()["sessions"]}
    assert short in listed, listed
    for s in (sid, short):
        (state / f"{s}.snap" / "blocker").rmdir()
        (state / f"{s}.snap").rmdir()
    assert http("DELETE", f"{url}/v1/sessions/{sid}", rec).status_code == 200
    assert http("GET", f"{url}/v1/sessions/{sid}", rec).status_code == 404
    time.sleep(2.0)
    listed = {s["id"] for s in http("GET", f"{url}/v1/sessions", rec).json()["sessions"]}
    assert short not in listed, listed
    rec.check()
    assert_clean_exit(server)


# --- Found in session 19 by an outside-style attack pass -------------------------------------


def test_a_second_server_cannot_take_a_state_directory_in_use(tmp_path):
    # Two servers on one --state-dir each trusted their own versions: one's acknowledged step was
    # overwritten by the other's save, and a session one deleted was written back by the other.
    state = tmp_path / "state"
    first = ServerProcess("--state-dir", str(state))
    url, rec = first.url, Recorder()
    sid = create(url, rec)
    with pytest.raises(RuntimeError, match="is in use by another process"):
        ServerProcess("--state-dir", str(state))
    assert http("GET", f"{url}/v1/sessions/{sid}", rec).status_code == 200
    assert_clean_exit(first)
    second = ServerProcess("--state-dir", str(state))  # the lock went with the first
    assert http("GET", f"{second.url}/v1/sessions/{sid}", rec).status_code == 200
    rec.check()
    assert_clean_exit(second)


def frame_cpu_seconds(server, rec, sid, body_for, timeout):
    """Plans a step of session `sid` (20 simulations), observes it with the body
    `body_for(action_id)` and returns the server's CPU seconds for the observation (a 200)."""
    url, pid = server.url, server.proc.pid
    action_id = http("POST", f"{url}/v1/sessions/{sid}:plan", rec,
                     json={"budget": {"simulations": 20}}).json()["actionId"]
    body = body_for(action_id)
    before = cpu_seconds(pid)
    r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=body, timeout=timeout)
    used = cpu_seconds(pid) - before
    assert r.status_code == 200, r.text
    return used


def test_a_frame_in_a_large_room_costs_what_the_view_covers(hostile_server):
    # The example session's world in a 38.5 m room (a 1.3 kB create) and frames of three 0.6 m
    # squares that ICP cannot fit from the reported pose: RANSAC computed features over the
    # whole prior map and ICP built a k-d tree over it for every frame (in a 39 m room 60 s for
    # the first frame and 20 s for each later one; bench/perception_attacks.py big-room).
    # Registration now uses the map within reach of the view, and the map itself is built in
    # tiles around the views: the first frame cost 7-8 s and kept 250-340 MB in this room while
    # it mapped the whole floor (bench/perception_attacks.py house), 0.5 s and 15 MB now.
    url, rec = hostile_server.url, Recorder()
    world = example("create_session_request.json")["world"]
    robot_state = example("observe_request_raw.json")["robotState"]
    world["room"] = {"min": [-19.25, -19.25], "max": [19.25, 19.25]}
    sid = create(url, rec, world=world)
    points = three_squares(-0.3, -0.3, 2.0)  # in the camera frame
    # A few points at the edges of registration_range (6 m) widen the view to its largest: the
    # map's RANSAC features there are thinned to max_ransac_map_points (5.2 s a frame before).
    # raw_observation's robot stands at (0.3, 0); the corner in the map frame before it.
    corner, spread = three_squares(1.2, -1.2, 1.6), registration_edge_points()
    # The spread frame is the first to reach that far: it builds the map's tiles out to
    # registration_range, 1.5-2 s of CPU on a 2-core machine (0.8 s when they are built), which
    # ASan makes 3-5x slower. The bound is for the 20-60 s of whole-room work.
    limit = 4.0 * (4 if SANITIZED else 1)
    for frame in ("first", "second", "spread"):
        def body_for(action_id):
            if frame == "spread":
                return raw_observation(action_id, corner + spread, "map")
            return dict(raw_observation(action_id, points), robotState=robot_state)

        used = frame_cpu_seconds(hostile_server, rec, sid, body_for, timeout=120)
        assert used < limit, f"the {frame} frame took {used:.1f} s of CPU"
    rec.check()


def test_a_frame_of_dense_volumes_costs_what_surfaces_cost(hostile_server):
    # RANSAC's FPFH features weigh every neighbour within 15 cm: a depth camera sees surfaces,
    # about 80 neighbours a point at the 3 cm voxels, but a map-frame lattice of 22^3 points 3 cm
    # apart beside 28 furniture shells 3 cm apart (a 2.6 kB create) gives each about 520, and a
    # frame cost 8.5 s of CPU (bench/perception_attacks.py nested-shells). Both clouds are
    # thinned until a bound on their neighbour pairs holds (max_ransac_pairs): 2.7 s.
    url, rec = hostile_server.url, Recorder()
    world = example("create_session_request.json")["world"]
    world["room"] = {"min": [-4, -4], "max": [4, 4]}
    world["furniture"] += [{"name": f"shell{i}", "center": [-2.5, -2.5],
                            "size": [0.3 + 0.03 * i] * 3, "yaw": 0.0, "workspace": False,
                            "color": [9, 9, 9]} for i in range(28)]
    sid = create(url, rec, world=world)
    lattice = [(-3.0 + 0.03 * i + 0.011, -3.0 + 0.03 * k + 0.007, 0.05 + 0.03 * m)
               for i in range(22) for k in range(22) for m in range(22)]
    limit = 5.0 * (4 if SANITIZED else 1)
    robot_state = {"x": -1.5, "y": -1.5, "yaw": 3.9, "lift": 0.2, "pan": 0, "tilt": 0.4}
    for frame in ("first", "second"):  # the first builds the session's prior map
        used = frame_cpu_seconds(
            hostile_server, rec, sid,
            lambda action_id: dict(raw_observation(action_id, lattice, "map"),
                                   robotState=robot_state), timeout=300)
        assert frame == "first" or used < limit, f"the {frame} frame took {used:.1f} s of CPU"
    rec.check()


def test_large_bodies_are_admitted_like_plans_before_they_are_parsed(hostile_server):
    """Target photos and an observation's images are decoded as the body is parsed (a 400 kB
    body of photos took 1.7 s of CPU; a stale observation's 50 kB image 0.2 s, every time).
    Bodies over 64 KiB now take a planning slot first: with both slots planning and the queue
    of 4 full, the rest are refused with Retry-After before they are parsed."""
    url, rec = hostile_server.url, Recorder()
    busy = [create(url, rec) for _ in range(2)]
    photo = base64.b64encode(noise_png(160)).decode()
    body = {"world": world_of("loose1"), "seed": 1, "planner": {"name": "kct", "particles": 50},
            "target": {"description": "x", "photos": [photo]}}
    assert len(json.dumps(body)) > 64 << 10
    sid, _ = planned(url, rec)
    stale = {"actionId": "stale", "succeeded": True,
             "image": {"encoding": "png", "data": photo}}
    codes = []

    def plan(s):
        r = http("POST", f"{url}/v1/sessions/{s}:plan", rec, json={"budget": {"timeMs": 3000}})
        codes.append(("plan", r.status_code))

    def large(kind):
        if kind == "create":
            r = http("POST", f"{url}/v1/sessions", rec, json=body)
        else:
            r = http("POST", f"{url}/v1/sessions/{sid}:observe", rec, json=stale)
        codes.append((kind, r.status_code, r.headers.get("Retry-After")))

    planners = [threading.Thread(target=plan, args=(s,)) for s in busy]
    for t in planners:
        t.start()
    time.sleep(0.5)  # both slots planning
    crowd = [threading.Thread(target=large, args=(k,)) for k in ["create", "observe"] * 5]
    for t in crowd:
        t.start()
    for t in crowd + planners:
        t.join()
    refused = [c for c in codes if c[0] != "plan" and c[1] == 429]
    assert len(refused) >= 6 and all(c[2] == "1" for c in refused), codes
    assert codes.count(("plan", 200)) == 2, codes
    rec.check()


def test_a_guessed_target_declarable_before_it_is_seen_is_refused(hostile_server):
    """With guessOdds past declareThreshold the planners chose to declare the guessed target,
    an action no observation could follow: the session was stuck for good."""
    url, rec = hostile_server.url, Recorder()
    for params in [{"guessOdds": 1.0, "declareThreshold": 0.6}, {"declareThreshold": 0.1}]:
        world = dict(world_of("loose1"), params=params)
        r = http("POST", f"{url}/v1/sessions", rec,
                 json={"world": world, "planner": {"name": "kct", "particles": 50}})
        assert r.status_code == 400 and field_of(r).startswith("world.params"), r.text
        assert "guess_odds" in r.text or "guessOdds" in r.text, r.text
    rec.check()

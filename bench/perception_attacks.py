#!/usr/bin/env python3
"""The perception attacks behind docs/api.md, "Perception under hostile input", one request each
against a real server, printing the status, the server's CPU seconds for the request and its peak
memory.

Usage: bench/perception_attacks.py ATTACK [N]   (server: NPFKCT_SERVER_BIN, default
build/bin/npfkct-server; run the build of another commit to see the "before" figures)
  far-blob N          a 1 mm blob of N points (default 20,000) beside three points 9,999 m away
  denormal            a cube off the table and two points 2e-20 m apart (SIGABRT before db9a0c5)
  sift-plates N       N thin plates on the camera's axis (default 30), fx 1e6, a flat 2048^2 image
  sift-photos N       N textured 2048^2 target photos (default 8), one plate filling the view
  ransac-lattice N    a cube and N lattice points (default 100,000), one per RANSAC voxel
  track-slabs N       N 1 cm slabs (default 9) grown into one track, then a restart
  big-room N          the example session's world in a room N m wide (default 39), two frames
                      of three 0.6 m squares that ICP cannot fit from the reported pose (RANSAC
                      runs each time)
  view-spread N       as big-room (default 16 m), the corner in the map frame beside twelve points
                      5.9 m from the camera: the view as wide as registration_range allows
  house N             N sessions (default 7) of the example world in a room 38.5 m wide (a 1.3 kB
                      create), one raw frame each (the outside check of issue 40: 20-29 s of CPU
                      and 220-350 MB kept per session when the first frame mapped the whole room),
                      the server's resident memory after each
  nested-shells N     the example world in an 8 m room with N furniture shells 3 cm apart (default
                      28) and map-frame frames of a 22^3 lattice 3 cm apart beside them (RANSAC's
                      FPFH: neighbours per point are not bounded)
"""
import base64
import os
import random
import struct
import sys
import tempfile
import zlib

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from conftest import ServerProcess  # noqa: E402
from test_hostile import (cpu_seconds, create, example, flat_png, http, noise_png,  # noqa: E402
                          raw_observation, registration_edge_points, three_squares)

FAR = [(9999.0, 9999.0, 9999.0), (-9999.0, 9999.0, 0.5), (0.001, -9999.0, 9999.0)]


def peak_mb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmHWM"):
            return int(line.split()[1]) / 1024
    return 0.0


def rss_mb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
    return 0.0


def observe(server, sid, body, label):
    pid = server.proc.pid
    before = cpu_seconds(pid)
    try:
        r = http("POST", f"{server.url}/v1/sessions/{sid}:observe", None, json=body, timeout=3600)
        what = f"status {r.status_code}"
        if r.status_code == 200 and "perception" in r.json():
            p = r.json()["perception"]
            what += f", {p['clusters']} clusters, registration {p['registration']}"
    except Exception as e:  # the server died or hung up
        what = f"no answer ({type(e).__name__}), server alive: {server.alive()}"
    print(f"{label}: {what}, server CPU {cpu_seconds(pid) - before:.1f} s, "
          f"peak memory {peak_mb(pid):.0f} MB", flush=True)


def cube(rnd, n=20000, hole=False):
    """The surface of a 0.6 m cube standing off loose1's table, which the map does not hold."""
    points = []
    for _ in range(n):
        u, v = rnd.uniform(-0.3, 0.3), rnd.uniform(-0.3, 0.3)
        face = rnd.randrange(6)
        a = 0.3 if face % 2 else -0.3
        x, y, z = [(a, u, v), (u, a, v), (u, v, a)][face // 2]
        if not (hole and abs(x) < 0.06 and -1.53 < y - 1.5 < -1.44 and z + 0.6 > 0.87):
            points.append((x, y - 1.5, z + 0.6))
    return points


def textured_png(size, seed):
    """A repeated 64-pixel noise tile: small to send, rich in SIFT keypoints."""
    rnd = random.Random(seed)
    tile = [bytes(rnd.randrange(256) for _ in range(3 * 64)) for _ in range(64)]
    def chunk(kind, payload):
        return (struct.pack(">I", len(payload)) + kind + payload +
                struct.pack(">I", zlib.crc32(kind + payload)))
    comp = zlib.compressobj(9)
    data = b"".join(comp.compress(b"\x00" + tile[y % 64] * (size // 64)) for y in range(size))
    return (b"\x89PNG\r\n\x1a\n" +
            chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", data + comp.flush()) + chunk(b"IEND", b""))


def on_axis(body, size, fx):
    """The robot at (0.3, 0) looking along +x (camera at about (0.45, 0, 1.08)), a size^2 camera."""
    body["robotState"] = {"x": 0.3, "y": 0, "yaw": 0, "lift": 0.0, "pan": 0, "tilt": 0.0}
    body["camera"] = {"width": size, "height": size, "fx": fx, "fy": fx, "cx": size / 2,
                      "cy": size / 2}
    return body


def main():
    attack = sys.argv[1] if len(sys.argv) > 1 else ""
    n = int(sys.argv[2]) if len(sys.argv) > 2 else None
    rnd = random.Random(1)
    state = tempfile.mkdtemp()
    server = ServerProcess("--state-dir", state, "--max-body-mb", "32")
    try:
        url = server.url
        if attack == "sift-photos":
            photos = [base64.b64encode(textured_png(2048, 7 + i)).decode() for i in range(n or 8)]
            sid = create(url, None, target={"description": "x", "photos": photos})
        elif attack == "sift-plates":
            photo = base64.b64encode(noise_png(64)).decode()
            sid = create(url, None, target={"description": "x", "photos": [photo]})
        elif attack in ("far-blob", "denormal", "ransac-lattice"):
            sid = create(url, None)
        elif attack in ("big-room", "view-spread"):
            world = example("create_session_request.json")["world"]
            half = (n or (39 if attack == "big-room" else 16)) / 2
            world["room"] = {"min": [-half, -half], "max": [half, half]}
            sid = create(url, None, world=world)
        elif attack == "house":
            world = example("create_session_request.json")["world"]
            world["room"] = {"min": [-19.25, -19.25], "max": [19.25, 19.25]}
            sid = None
        elif attack == "nested-shells":
            world = example("create_session_request.json")["world"]
            world["room"] = {"min": [-4, -4], "max": [4, 4]}
            world["furniture"] += [{"name": f"shell{i}", "center": [-2.5, -2.5],
                                    "size": [0.3 + 0.03 * i] * 3, "yaw": 0.0, "workspace": False,
                                    "color": [9, 9, 9]} for i in range(n or 28)]
            sid = create(url, None, world=world)
        elif attack == "track-slabs":
            world = {"robot": "fetch", "room": {"min": [-1, -1], "max": [9, 6]},
                     "mapResolution": 0.05,
                     "furniture": [{"name": "table", "center": [5.0, 2.5], "size": [4.0, 3.0, 0.75],
                                    "yaw": 0.0, "workspace": True, "color": [139, 105, 70]}],
                     "baseRegions": [{"min": [0.0, 0.0], "max": [2.0, 1.0]}],
                     "discretePoses": [{"x": 1.0, "y": 0.5, "yaw": 0.0}],
                     "start": {"x": 1.0, "y": 0.5, "yaw": 0.0, "lift": 0.0, "pan": 0.0,
                               "tilt": 0.0}}
            sid = http("POST", url + "/v1/sessions", None,
                       json={"world": world, "seed": 1,
                             "planner": {"name": "kct", "particles": 50}}).json()["id"]
        else:
            sys.exit(__doc__)

        def action():
            return http("POST", f"{url}/v1/sessions/{sid}:plan", None,
                        json={"budget": {"simulations": 20}}).json()["actionId"]

        if attack == "far-blob":
            blob = [(1.2 + 0.001 * rnd.random(), -0.3 + 0.001 * rnd.random(),
                     0.8 + 0.001 * rnd.random()) for _ in range(n or 20000)]
            observe(server, sid, raw_observation(action(), FAR + blob, "map"), attack)
        elif attack == "denormal":
            points = cube(rnd, hole=True) + [(1e-20, -1.485, 0.915), (-1e-20, -1.485, 0.915)]
            observe(server, sid, raw_observation(action(), points, "map"), attack)
        elif attack == "sift-plates":
            points = [(1.025 + 0.04 * k, 0.005 + 0.01 * i, 1.085 + 0.01 * j)
                      for k in range(n or 30) for i in range(-3, 4) for j in range(-3, 3)]
            body = on_axis(raw_observation(action(), points, "map"), 2048, 1e6)
            body["image"] = {"data": base64.b64encode(flat_png(2048, 2048)).decode()}
            observe(server, sid, body, attack)
        elif attack == "sift-photos":
            fx, x = 6650.0, 2.195  # a plate filling the view
            h = 1024 / fx * (x - 0.45) + 0.01
            m = int(2 * h / 0.01) + 1
            points = [(x, -h + 0.01 * i, 1.08 - h + 0.01 * j) for i in range(m) for j in range(m)]
            # A first frame without an image builds the session's perception (the photos' SIFT).
            observe(server, sid, on_axis(raw_observation(action(), points, "map"), 2048, fx),
                    attack + " (first frame: photos)")
            body = on_axis(raw_observation(action(), points, "map"), 2048, fx)
            body["image"] = {"data": base64.b64encode(textured_png(2048, 5)).decode()}
            observe(server, sid, body, attack)
        elif attack == "ransac-lattice":
            pitch, points = 0.03, cube(rnd)
            ys = [(i + 0.5) * pitch for i in range(int(-2.5 / pitch), int(-0.6 / pitch))] + \
                 [(i + 0.5) * pitch for i in range(int(0.6 / pitch), int(3.0 / pitch))]
            zs = [(i + 0.5) * pitch for i in range(int(0.1 / pitch), int(2.5 / pitch))]
            x, wanted = (int(-2.5 / pitch) + 0.5) * pitch, len(points) + (n or 100000)
            while len(points) < wanted:
                points += [(x, y, z) for y in ys for z in zs][:wanted - len(points)]
                x += pitch
            observe(server, sid, raw_observation(action(), points, "map"), attack)
        elif attack == "big-room":
            points = three_squares(-0.3, -0.3, 2.0)  # in the camera frame
            robot_state = example("observe_request_raw.json")["robotState"]
            for label in ("first frame (builds the prior map)", "second frame"):
                body = raw_observation(action(), points)
                body["robotState"] = robot_state
                observe(server, sid, body, f"{attack} {label}")
        elif attack == "house":
            points = three_squares(-0.3, -0.3, 2.0)  # in the camera frame
            robot_state = example("observe_request_raw.json")["robotState"]
            print(f"house: server before any session: {rss_mb(server.proc.pid):.0f} MB resident")
            for i in range(n or 7):
                sid = create(url, None, world=world)
                body = raw_observation(action(), points)
                body["robotState"] = robot_state
                observe(server, sid, body, f"house session {i + 1}, its first frame")
                print(f"house: {i + 1} sessions, server {rss_mb(server.proc.pid):.0f} MB resident",
                      flush=True)
        elif attack == "view-spread":
            corner, spread = three_squares(1.2, -1.2, 1.6), registration_edge_points()
            observe(server, sid, raw_observation(action(), corner, "map"),
                    f"{attack} first frame, the corner alone (builds the prior map)")
            for i in range(2):
                observe(server, sid, raw_observation(action(), corner + spread, "map"),
                        f"{attack} frame {i + 2}, the corner and the spread points")
        elif attack == "nested-shells":
            lattice = [(-3.0 + 0.03 * i + 0.011, -3.0 + 0.03 * k + 0.007, 0.05 + 0.03 * m)
                       for i in range(22) for k in range(22) for m in range(22)]
            for i in range(3):
                body = raw_observation(action(), lattice, "map")
                body["robotState"] = {"x": -1.5, "y": -1.5, "yaw": 3.9, "lift": 0.2, "pan": 0,
                                      "tilt": 0.4}
                observe(server, sid, body, f"{attack} frame {i + 1}")
        elif attack == "track-slabs":
            c = lambda i: (i + 0.5) * 0.01  # noqa: E731
            x0, x1, y0, y1, z0, z1 = 302, 698, 102, 398, 78, 130  # the box's voxel indices
            wire = {(x, y, z) for x in range(x0, x1 + 1) for y in (y0, y1) for z in (z0, z1)}
            wire |= {(x, y, z) for y in range(y0, y1 + 1) for x in (x0, x1) for z in (z0, z1)}
            wire |= {(x, y, z) for z in range(z0, z1 + 1) for x in (x0, x1) for y in (y0, y1)}
            frames = [[(c(x), c(y), c(z)) for x, y, z in wire]]
            for k in range(n or 9):
                z = z0 + 2 + 5 * k
                frames.append([(c(x), c(y), c(z)) for x in range(x0 + 2, x1 - 1)
                               for y in range(y0 + 2, y1 - 1)])
            for i, points in enumerate(frames):
                body = raw_observation(action(), points, "map")
                body["robotState"] = {"x": 1.0, "y": 2.5, "yaw": 0, "lift": 0.0, "pan": 0,
                                      "tilt": 0.0}
                observe(server, sid, body, f"{attack} frame {i}")
    finally:
        print("server exit status", server.stop())
    if attack == "track-slabs":
        again = ServerProcess("--state-dir", state, "--max-body-mb", "32")
        try:
            r = http("GET", f"{again.url}/v1/sessions/{sid}", None)
            print("after a restart the session answers", r.status_code)
        finally:
            again.stop()


if __name__ == "__main__":
    main()

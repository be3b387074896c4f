#!/usr/bin/env python3
"""Regenerates schemas/examples/ from a live npfkct-server and the simulated robot, so that every
example is something the server really sent or accepted. Usage (after a build):

    python3 tools/gen_schema_examples.py [build_dir]

The raw-frame examples are cut down to stay readable: the point cloud keeps its first 40 points
and the image is a 16 x 12 grey PNG with matching intrinsics (the full 640 x 480 frame is 5 MB
of base64); both are still accepted by the server."""

import base64
import json
import os
import struct
import sys
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("NPFKCT_BUILD_DIR", sys.argv[1] if len(sys.argv) > 1 else
                      os.path.join(ROOT, "build"))
sys.path.insert(0, os.path.join(ROOT, "tests"))

import requests  # noqa: E402

from conftest import ServerProcess, SimRobot, world_of  # noqa: E402

OUT = os.path.join(ROOT, "schemas", "examples")


def write(name, body):
    with open(os.path.join(OUT, name + ".json"), "w", encoding="utf-8") as f:
        json.dump(body, f, indent=2, sort_keys=True)
        f.write("\n")


def grey_png(width, height):
    def chunk(kind, payload):
        return (struct.pack(">I", len(payload)) + kind + payload +
                struct.pack(">I", zlib.crc32(kind + payload)))
    rows = b"".join(b"\x00" + b"\x80" * (3 * width) for _ in range(height))
    return (b"\x89PNG\r\n\x1a\n" +
            chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def main():
    server = ServerProcess()
    url = server.url
    try:
        write("health", requests.get(url + "/healthz").json())
        write("list_planners_response", requests.get(url + "/v1/planners").json())
        create = {"displayName": "kitchen search", "world": world_of("loose1"), "seed": 42,
                  "planner": {"name": "npfkct", "particles": 300, "model": "filter.pt",
                              "options": {"k": 3, "dLim": 0.2}},
                  "target": {"description": "blue snack box"},
                  "ttlSeconds": 1800}
        write("create_session_request", create)
        session = requests.post(url + "/v1/sessions", json=create).json()
        write("session", session)
        sid = session["id"]
        write("plan_request", {"budget": {"timeMs": 200}})
        write("empty", {})
        robot = SimRobot("loose1", seed=42)
        plan = requests.post(url + f"/v1/sessions/{sid}:plan",
                             json={"budget": {"timeMs": 200}}).json()
        write("plan_response", plan)
        body = dict(robot.execute(plan["action"])["observation"], actionId=plan["actionId"])
        write("observe_request", body)
        write("observe_response",
              requests.post(url + f"/v1/sessions/{sid}:observe", json=body).json())
        robot.close()
        write("steps_response", requests.get(url + f"/v1/sessions/{sid}/steps").json())
        write("belief", requests.get(url + f"/v1/sessions/{sid}/belief").json())
        write("list_sessions_response", requests.get(url + "/v1/sessions?pageSize=1").json())
        write("error", requests.post(url + f"/v1/sessions/{sid}:plan",
                                     json={"budget": {"timeMs": -1}}).json())

        # Raw sensor data: a cut-down frame of the rendered camera.
        raw_robot = SimRobot("loose1", seed=42, raw=True)
        raw = requests.post(url + "/v1/sessions", json={
            "world": world_of("loose1"), "seed": 42,
            "target": {"description": "patterned box",
                       "photos": [base64.b64encode(p).decode()
                                  for p in raw_robot.target_photos()[:1]]}}).json()
        rid = raw["id"]
        plan = requests.post(url + f"/v1/sessions/{rid}:plan",
                             json={"budget": {"timeMs": 100}}).json()
        observation = raw_robot.execute(plan["action"])["observation"]
        raw_robot.close()
        assert "pointCloud" in observation, "the first view saw nothing"
        points = base64.b64decode(observation["pointCloud"]["data"])[:40 * 16]
        scale = 16 / observation["camera"]["width"]
        small = {
            "actionId": plan["actionId"],
            "succeeded": observation["succeeded"],
            "robotState": observation["robotState"],
            "pointCloud": {"frame": "camera", "fields": "xyzrgb",
                           "data": base64.b64encode(points).decode()},
            "image": {"encoding": "png", "data": base64.b64encode(grey_png(16, 12)).decode()},
            "camera": {"width": 16, "height": 12,
                       "fx": observation["camera"]["fx"] * scale,
                       "fy": observation["camera"]["fy"] * scale,
                       "cx": observation["camera"]["cx"] * scale,
                       "cy": observation["camera"]["cy"] * scale},
        }
        write("observe_request_raw", small)
        reply = requests.post(url + f"/v1/sessions/{rid}:observe", json=small)
        assert reply.status_code == 200, reply.text
        write("observe_response_raw", reply.json())
    finally:
        server.stop()


if __name__ == "__main__":
    main()

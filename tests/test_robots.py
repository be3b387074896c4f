"""Any robot through the real server: a session's robot from its URDF (robot/urdf/) or from a
description of its camera chain; plans stay within the robot's joints, and a robot without a
lift plans with the lift at 0. Bad robots get a 400 naming the field. A robot of its own on a
SLAM map with its detector's boxes finds the target."""

import json
import math
import os
import subprocess
import tempfile

import pytest
import requests

from conftest import ROBOT_BIN, ROOT, ServerProcess, world_of
from npfkct_client import slam_world, write_map_files


def urdf(name):
    with open(os.path.join(ROOT, "robot", "urdf", name), encoding="utf-8") as f:
        return f.read()


FETCH = {"name": "fetch-urdf", "baseLink": "base_link",
         "cameraLink": "head_camera_rgb_optical_frame", "opticalFrame": True,
         "liftJoint": "torso_lift_joint", "panJoint": "head_pan_joint",
         "tiltJoint": "head_tilt_joint"}
STRETCH = {"name": "stretch-urdf", "baseLink": "base_link", "cameraLink": "camera_link",
           "panJoint": "joint_head_pan", "tiltJoint": "joint_head_tilt", "footprintRadius": 0.2,
           "reach": 0.8}


def create(url, robot, scenario="loose1"):
    world = world_of(scenario)
    world["robot"] = robot
    return requests.post(url + "/v1/sessions", json={
        "world": world, "seed": 4, "planner": {"name": "kct", "particles": 100}}, timeout=60)


def moves(url, sid, n):
    """The configurations of n planned moves (each observed with nothing seen)."""
    out = []
    for _ in range(n):
        r = requests.post(f"{url}/v1/sessions/{sid}:plan", json={"budget": {"simulations": 300}},
                          timeout=60)
        assert r.status_code == 200, r.text
        action = r.json()["action"]
        if action["type"] != "MOVE":
            break
        out.append(action["configuration"])
        r = requests.post(f"{url}/v1/sessions/{sid}:observe",
                          json={"actionId": r.json()["actionId"], "detections": [],
                                "robotState": action["configuration"]}, timeout=60)
        assert r.status_code == 200, r.text
    return out


def sim_step(url, sid, sim, budget):
    """One step of an episode: the server plans within `budget`, the simulated robot executes
    the action, the server takes its observation. Gives the action, the robot's reply, the
    :observe body sent and the server's answer."""
    plan = requests.post(f"{url}/v1/sessions/{sid}:plan", json={"budget": budget},
                         timeout=60).json()
    action = plan["action"]
    sim.stdin.write(json.dumps(action) + "\n")
    sim.stdin.flush()
    reply = json.loads(sim.stdout.readline())
    body = dict(reply["observation"], actionId=plan["actionId"])
    o = requests.post(f"{url}/v1/sessions/{sid}:observe", json=body, timeout=60)
    assert o.status_code == 200, o.text[:300]
    return action, reply, body, o.json()


def test_robots_from_their_urdfs_plan_within_their_joints():
    server = ServerProcess("--state-dir", tempfile.mkdtemp())
    try:
        r = create(server.url, dict(FETCH, urdf=urdf("fetch_head.urdf")))
        assert r.status_code == 200, r.text
        fetch = moves(server.url, r.json()["id"], 3)
        assert fetch, "no move planned"
        for c in fetch:
            assert 0.0 <= c["lift"] <= 0.386 and -1.57 <= c["pan"] <= 1.57, c
            assert -0.76 <= c["tilt"] <= 1.45, c
        r = create(server.url, dict(STRETCH, urdf=urdf("stretch_head.urdf")), "fig16")
        assert r.status_code == 200, r.text
        stretch = moves(server.url, r.json()["id"], 3)
        assert stretch and all(c["lift"] == 0.0 for c in stretch), stretch
        # A description of the camera chain: a fixed 1.1 m mast and a pan, no tilt, no lift.
        mast = {"name": "mast", "joints": [
            {"type": "fixed", "xyz": [0.1, 0, 1.1]},
            {"name": "pan", "type": "revolute", "role": "pan", "axis": [0, 0, 1],
             "lower": -1.0, "upper": 1.0}]}
        r = create(server.url, mast)
        assert r.status_code == 200, r.text
        for c in moves(server.url, r.json()["id"], 2):
            assert c["lift"] == 0.0 and c["tilt"] == 0.0 and -1.0 <= c["pan"] <= 1.0, c
    finally:
        assert server.stop() == 0


def test_bad_robots_name_the_field():
    server = ServerProcess("--state-dir", tempfile.mkdtemp())
    try:
        cases = [
            (dict(FETCH, urdf=urdf("fetch_head.urdf"), baseLink="nope"), "world.robot.baseLink"),
            (dict(FETCH, urdf=urdf("fetch_head.urdf"), panJoint="shoulder_pan_joint"),
             "world.robot.panJoint"),
            (dict(FETCH, urdf="<robot name='x'><link"), "world.robot.urdf"),
            (dict(FETCH, urdf="<robot name='r'>" + "<link name='a'>" * 50000 + "</robot>"),
             "world.robot.urdf"),
            ({"joints": [{"type": "revolute", "role": "lift", "axis": [0, 0, 1]}]},
             "world.robot.joints[0].role"),
            ({"joints": [{"type": "prismatic", "axis": [0, 0, 0]}]}, "world.robot.joints[0].axis"),
            ("roomba", "world.robot"),
            ({"joints": [], "footprint": [[0, 0], [0.4, 0.2], [0.4, 0], [0, 0.4]]},
             "world.robot.footprint[2]"),
            ({"joints": [], "footprint": [[0, 0], [0.5, 0], [1.0, 0]]}, "world.robot.footprint"),
            (dict(FETCH, urdf=urdf("fetch_head.urdf"), footprint=[[0, 0], [9, 0], [0, 1]]),
             "world.robot.footprint[1]"),
        ]
        for robot, field in cases:
            r = create(server.url, robot)
            assert r.status_code == 400, (field, r.status_code, r.text[:300])
            fields = [v["field"] for d in r.json()["error"]["details"]
                      for v in d.get("fieldViolations", [])]
            assert fields[:1] == [field], (field, r.text[:300])
        assert requests.get(server.url + "/healthz", timeout=5).status_code == 200
    finally:
        assert server.stop() == 0


def test_mutated_urdfs_get_an_answer_and_never_hurt_the_server():
    """300 Fetch URDFs with random edits (tags cut or doubled, quotes dropped, numbers made
    huge, NaN or negative, joints retyped): each gets a 200 or a 400, and the server lives."""
    import random
    rng = random.Random(7)
    text = urdf("fetch_head.urdf")
    edits = ["<", ">", "\"", "'", "/>", "</link>", "<link name='x'>", "nan", "1e999", "-1e308",
             "inf", "type=\"floating\"", "type=\"planar\"", "<!--", "]]>", "&amp;", "&#0;",
             "<joint name='j' type='revolute'><parent link='base_link'/><child link='base_link'/>"
             "</joint>", "\u00e9", "0 0 0", "xyz=\"1 2\"", "rpy=\"a b c\""]
    server = ServerProcess("--state-dir", tempfile.mkdtemp())
    try:
        for i in range(300):
            t = text
            for _ in range(rng.randint(1, 4)):
                at = rng.randrange(len(t))
                if rng.random() < 0.5:
                    t = t[:at] + rng.choice(edits) + t[at:]
                else:
                    t = t[:at] + t[at + rng.randint(1, 20):]
            r = create(server.url, dict(FETCH, urdf=t))
            assert r.status_code in (200, 400), (i, r.status_code, r.text[:200])
            if r.status_code == 400:
                assert r.json()["error"]["message"].startswith("world.robot"), r.text[:200]
        assert requests.get(server.url + "/healthz", timeout=5).status_code == 200
    finally:
        assert server.stop() == 0


DIFFDRIVE = {"name": "diffdrive", "baseLink": "base_link", "cameraLink": "camera_link",
             "footprintRadius": 0.25, "reach": 0.8}
# The same robot as a description: one fixed joint from the base to the camera (the URDF's mast
# and camera joints composed: 0.1 m forward, 1.1 m up, pitched down 0.5 rad).
DIFFDRIVE_JSON = {"name": "diffdrive", "footprintRadius": 0.25, "reach": 0.8,
                  "joints": [{"name": "camera_mount", "type": "fixed", "xyz": [0.1, 0.0, 1.1],
                              "rpy": [0.0, 0.5, 0.0]}]}


@pytest.mark.parametrize("form,scene", [("urdf", "loose1"), ("description", "loose1"),
                                        ("urdf", "generated")])
def test_a_robot_of_its_own_on_a_slam_map_with_a_detectors_boxes_finds_the_target(
        form, scene, tmp_path):
    """Issue 40's end-to-end path: a differential base with a fixed camera (no lift, no pan, no
    tilt to plan) from its URDF or its description, on the scene's room given as map_server's
    YAML + PGM with the workspaces traced (Loose1, and a generated scene: npfkct-scenegen's seed
    15, four pieces of furniture; a fixed camera needs 16-32 steps and more in others), the
    simulated robot rendering with that robot's camera and reporting its detector's 2D boxes
    with the depth: the target is found."""
    robot = (dict(DIFFDRIVE, urdf=urdf("diffdrive_fixed_camera.urdf")) if form == "urdf"
             else DIFFDRIVE_JSON)
    if scene == "loose1":
        with open(os.path.join(ROOT, "scenarios", "loose1.json"), encoding="utf-8") as f:
            scenario = json.load(f)
    else:
        scenario = json.loads(subprocess.run(
            [os.path.join(os.path.dirname(ROBOT_BIN), "npfkct-scenegen"), "--seed", "15",
             "--placement", "open"], check=True, capture_output=True, text=True).stdout)
    scenario["robot"] = robot  # the simulated robot renders with this robot's camera
    scenario_path = str(tmp_path / "scene-diffdrive.json")
    with open(scenario_path, "w", encoding="utf-8") as f:
        json.dump(scenario, f)
    world = slam_world(scenario, write_map_files(scenario, str(tmp_path)))
    server = ServerProcess()
    sim = subprocess.Popen([ROBOT_BIN, "--scenario", scenario_path, "--seed", "3", "--boxes"],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        r = requests.post(server.url + "/v1/sessions", json={"world": world, "seed": 3},
                          timeout=60)
        assert r.status_code == 200, r.text
        sid, done, boxed = r.json()["id"], False, 0
        for _ in range(40):
            # A fixed number of simulations, not CPU time: the same episode on a busy machine.
            action, reply, body, observed = sim_step(server.url, sid, sim, {"simulations": 500})
            if action["type"] == "MOVE":  # the base pose alone: nothing else moves the camera
                c = action["configuration"]
                assert (c["lift"], c["pan"], c["tilt"]) == (0.0, 0.0, 0.0), c
            boxed += bool(body.get("imageBoxes"))
            done = observed["done"]
            assert done == reply["outcome"]["terminal"]
            if done:
                break
        assert done, "the target was not removed within 40 steps"
        assert boxed > 0
    finally:
        sim.stdin.close()
        sim.wait(timeout=10)
        assert server.stop() == 0


def test_a_robots_camera_is_its_own(server):
    """A description's camera (field of view, depth range) is what the session sees with: a
    camera that sees half as far draws a smaller frustum; a bad one is a 400 naming the field."""
    def frustum_area(robot):
        r = create(server.url, robot)
        assert r.status_code == 200, r.text
        polygon = requests.get(f"{server.url}/v1/sessions/{r.json()['id']}/belief",
                               timeout=30).json()["camera"]["frustum"]
        return 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1)
                             in zip(polygon, polygon[1:] + polygon[:1])))
    wide = frustum_area(DIFFDRIVE_JSON)
    short = frustum_area(dict(DIFFDRIVE_JSON, camera={"far": 1.1}))
    assert 0 < short < 0.8 * wide, (short, wide)
    for camera, field in (({"near": 2.0, "far": 1.0}, "world.robot.camera.near"),
                          ({"horizontalFov": 3.1}, "world.robot.camera.horizontalFov"),
                          ({"far": 60}, "world.robot.camera.far")):
        r = create(server.url, dict(DIFFDRIVE_JSON, camera=camera))
        assert r.status_code == 400, r.text
        assert r.json()["error"]["details"][0]["fieldViolations"][0]["field"] == field, r.text


def _corners(center, size, yaw):
    """A box's (or a rectangle's) corners in the plane."""
    c, s = math.cos(yaw), math.sin(yaw)
    return [(center[0] + c * u - s * v, center[1] + s * u + c * v)
            for u, v in ((-size[0] / 2, -size[1] / 2), (size[0] / 2, -size[1] / 2),
                         (size[0] / 2, size[1] / 2), (-size[0] / 2, size[1] / 2))]


def _overlap(p, q):
    """Whether two convex polygons overlap (separating axis theorem)."""
    for poly in (p, q):
        for (x0, y0), (x1, y1) in zip(poly, poly[1:] + poly[:1]):
            nx, ny = y0 - y1, x1 - x0
            a = [nx * x + ny * y for x, y in p]
            b = [nx * x + ny * y for x, y in q]
            if max(a) <= min(b) or max(b) <= min(a):
                return False
    return True


# A long, narrow base (a 0.8 m x 0.36 m cart) with Fetch's head chain.
CART = [[0.4, 0.18], [-0.4, 0.18], [-0.4, -0.18], [0.4, -0.18]]


def test_a_rectangular_base_plans_where_its_outline_fits_and_finds_the_target(tmp_path):
    """A robot whose footprint is a polygon: the simulated robot moves it (its outline against
    the map), every base the server plans keeps the outline clear of the furniture at the planned
    heading, the target is found, and the outline is the belief's (and survives a restart)."""
    robot = {"name": "cart", "footprint": CART, "reach": 0.9,
             "joints": [{"type": "fixed", "xyz": [0.2, 0.0, 1.0]},
                        {"name": "pan", "type": "revolute", "role": "pan", "axis": [0, 0, 1],
                         "lower": -1.5, "upper": 1.5},
                        {"name": "tilt", "type": "revolute", "role": "tilt", "axis": [0, 1, 0],
                         "lower": 0.0, "upper": 1.0}]}
    with open(os.path.join(ROOT, "scenarios", "loose1.json"), encoding="utf-8") as f:
        scenario = json.load(f)
    scenario["robot"] = robot
    scenario_path = str(tmp_path / "loose1-cart.json")
    with open(scenario_path, "w", encoding="utf-8") as f:
        json.dump(scenario, f)
    world = world_of("loose1")
    world["robot"] = robot
    state = str(tmp_path / "state")
    server = ServerProcess("--state-dir", state)
    sim = subprocess.Popen([ROBOT_BIN, "--scenario", scenario_path, "--seed", "2"],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        r = requests.post(server.url + "/v1/sessions", json={"world": world, "seed": 2},
                          timeout=60)
        assert r.status_code == 200, r.text
        sid, done, bases = r.json()["id"], False, 0
        belief = requests.get(f"{server.url}/v1/sessions/{sid}/belief", timeout=10).json()
        assert belief["robotFootprint"] == CART
        assert belief["robotRadius"] == pytest.approx(math.hypot(0.4, 0.18))
        for _ in range(30):
            action, reply, _, observed = sim_step(server.url, sid, sim, {"simulations": 300})
            if action["type"] == "MOVE":
                c = action["configuration"]
                outline = [(c["x"] + math.cos(c["yaw"]) * x - math.sin(c["yaw"]) * y,
                            c["y"] + math.sin(c["yaw"]) * x + math.cos(c["yaw"]) * y)
                           for x, y in CART]
                for f in world["furniture"]:
                    assert not _overlap(outline, _corners(f["center"], f["size"],
                                                          f.get("yaw", 0.0))), (c, f["name"])
                bases += 1
            assert reply["outcome"].get("detail") != "base pose collides with the map", reply
            done = observed["done"]
            if done:
                break
        assert done and bases > 0
        assert server.stop() == 0
        server = ServerProcess("--state-dir", state)
        belief = requests.get(f"{server.url}/v1/sessions/{sid}/belief", timeout=10).json()
        assert belief["robotFootprint"] == CART
    finally:
        sim.stdin.close()
        sim.wait(timeout=10)
        assert server.stop() == 0

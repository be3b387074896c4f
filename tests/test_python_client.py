"""Full episodes through the Python client against the real server."""

import base64
import concurrent.futures
import json
import os
import re
import shutil
import struct
import subprocess
import sys
import time

import pytest

from conftest import ROOT, SCENARIOS, SimRobot, world_of

from npfkct_client import (ApiError, Box, Detection, Face, ImageBox, NpfkctClient, PointCloud,
                           RobotConfig, World)


def run_episode(client, scenario, planner="npfkct", time_ms=250, max_steps=50):
    session = client.create_session(world_of(scenario), planner=planner, seed=3)
    robot = SimRobot(scenario, seed=3)
    try:
        for step in range(1, max_steps + 1):
            plan = client.plan(session.id, time_ms=time_ms)
            assert plan.session.state == "ACTION_PENDING"
            reply = robot.execute(plan.action.to_json())
            observed = client.observe(session.id, plan.action_id, body=reply["observation"])
            assert observed.done == reply["outcome"]["terminal"]
            if observed.done:
                assert observed.session.state == "DONE"
                return step
        return None
    finally:
        robot.close()
        client.delete_session(session.id)


def test_full_episode_loose1(server):
    client = NpfkctClient(server.url)
    assert client.health()["status"] == "SERVING"
    steps = run_episode(client, "loose1")
    assert steps is not None and steps <= 50
    assert "npfkct_plans_total" in client.metrics()


@pytest.mark.parametrize("planner", ["gpomcp", "pomcpow"])
def test_other_planners_serve_episodes(server, planner):
    client = NpfkctClient(server.url)
    assert run_episode(client, "loose1", planner=planner) is not None


def drive_frames(client, session, robot, observe_frame, steps=30):
    """Plans and executes up to `steps` steps, observing each rendered frame with
    observe_frame(plan, observation body) (a step whose camera saw nothing in range goes as the
    body); ends the session; asserts the target was removed."""
    try:
        for _ in range(steps):
            plan = client.plan(session.id, time_ms=250)
            reply = robot.execute(plan.action.to_json())
            o = reply["observation"]
            if "pointCloud" not in o:  # the camera saw nothing in range
                observed = client.observe(session.id, plan.action_id, body=o)
            else:
                observed = observe_frame(plan, o)
            assert observed.done == reply["outcome"]["terminal"]
            if observed.done:
                break
        assert observed.done, f"the target was not removed within {steps} steps"
    finally:
        robot.close()
        client.delete_session(session.id)


def test_raw_frames_through_the_typed_client(server):
    """Rendered RGB-D frames sent as PointCloud + PNG: the server's perception finds the
    objects and the episode ends with the target removed."""
    client = NpfkctClient(server.url)
    robot = SimRobot("loose1", seed=4, raw=True)
    session = client.create_session(world_of("loose1"), seed=4,
                                    target_description="patterned box",
                                    target_photos=robot.target_photos())
    assert session.raw["target"] == {"description": "patterned box", "photoCount": 4}
    seen = set()

    def observe_frame(plan, o):
        observed = client.observe(
            session.id, plan.action_id, succeeded=o["succeeded"],
            robot_state=RobotConfig.from_json(o["robotState"]),
            point_cloud=PointCloud(base64.b64decode(o["pointCloud"]["data"]), "xyzrgb"),
            image=base64.b64decode(o["image"]["data"]), camera=o["camera"])
        assert observed.perception["timingsMs"]["total"] > 0
        seen.update(d["id"] for d in observed.perception["detections"])
        return observed

    drive_frames(client, session, robot, observe_frame)
    assert len(seen) >= 2 and all(i.startswith("obj-") for i in seen)


def test_a_detectors_boxes_through_the_typed_client(server):
    """The robot's own detector: depth as a PointCloud and 2D boxes of the target as ImageBoxes,
    no photos and no image. The episode ends with the target removed, and the reply says which
    object each box went to."""
    client = NpfkctClient(server.url)
    robot = SimRobot("hidden1", seed=5, boxes=True)
    session = client.create_session(world_of("hidden1"), seed=5)
    boxed = set()

    def observe_frame(plan, o):
        assert "image" not in o
        boxes = [ImageBox.from_xyxy(b["x"], b["y"], b["x"] + b["width"], b["y"] + b["height"],
                                    b["score"]) for b in o["imageBoxes"]]
        observed = client.observe(
            session.id, plan.action_id, succeeded=o["succeeded"],
            robot_state=RobotConfig.from_json(o["robotState"]),
            point_cloud=PointCloud(base64.b64decode(o["pointCloud"]["data"]), "xyzrgb"),
            camera=o["camera"], image_boxes=boxes)
        given = observed.perception.get("boxObjects", [])
        assert len(given) == len(boxes)
        boxed.update(i for i in given if i is not None)
        return observed

    drive_frames(client, session, robot, observe_frame)
    assert boxed and all(i.startswith("obj-") for i in boxed)


def test_3d_boxes_with_one_score_each(server):
    """A 3D box detector's output: each object's box with one score, typed as Detection(score=);
    the server gives the score to the faces the camera sees and the episode ends."""
    client = NpfkctClient(server.url)
    robot = SimRobot("covered1", seed=2, boxes3d=True)
    session = client.create_session(world_of("covered1"), seed=2)
    try:
        for _ in range(40):
            plan = client.plan(session.id, time_ms=250)
            reply = robot.execute(plan.action.to_json())
            o = reply["observation"]
            detections = [Detection(d["id"], Box(d["box"]["center"], d["box"]["size"]),
                                    moveability=d["moveability"], score=d.get("score"))
                          for d in o["detections"]]
            assert all("faces" not in d for d in o["detections"])
            observed = client.observe(session.id, plan.action_id, succeeded=o["succeeded"],
                                      robot_state=RobotConfig.from_json(o["robotState"]),
                                      detections=detections)
            assert observed.done == reply["outcome"]["terminal"]
            if observed.done:
                break
        assert observed.done, "the target was not removed within 40 steps"
    finally:
        robot.close()
        client.delete_session(session.id)


def test_one_score_and_face_scores_together_are_refused(server):
    client = NpfkctClient(server.url)
    session = client.create_session(world_of("loose1"), seed=1)
    plan = client.plan(session.id, simulations=50)
    assert plan.action.type == "MOVE"
    box = {"center": [1.9, -0.2, 0.83], "size": [0.1, 0.1, 0.1]}
    cases = [({"id": "b", "box": box, "score": 0.9, "faces": [{"corner": 0, "score": 0.9}]},
              "detections[0].faces"),
             ({"id": "b", "box": box, "score": 2}, "detections[0].score")]
    for detection, field in cases:
        with pytest.raises(ApiError) as e:
            client.observe(session.id, plan.action_id,
                           body={"robotState": plan.action.configuration.to_json(),
                                 "detections": [detection]})
        assert e.value.http_status == 400 and e.value.field == field, e.value.message
    client.delete_session(session.id)


def test_depth_images_and_detector_boxes_pack():
    camera = {"fx": 2.0, "fy": 4.0, "cx": 1.0, "cy": 1.0}
    cloud = PointCloud.from_depth([[2.0, 0.0], [float("nan"), 1.0]], camera)
    assert cloud.fields == "xyz" and cloud.frame == "camera" and len(cloud.data) == 24
    assert struct.unpack("<6f", cloud.data) == pytest.approx(
        ((0.5 - 1.0) / 2.0 * 2.0, (0.5 - 1.0) / 4.0 * 2.0, 2.0,
         (1.5 - 1.0) / 2.0, (1.5 - 1.0) / 4.0, 1.0))
    box = ImageBox.from_xyxy(10, 20, 110, 70, 0.9)
    assert box.to_json() == {"x": 10.0, "y": 20.0, "width": 100.0, "height": 50.0, "score": 0.9}


def test_point_cloud_packing():
    cloud = PointCloud.from_points([(1.0, 2.0, 3.0), (float("nan"), 0.0, 1.0)])
    assert cloud.fields == "xyz" and len(cloud.data) == 12
    coloured = PointCloud.from_points([(1.0, 2.0, 3.0)], colors=[(255, 0, 1)])
    assert coloured.fields == "xyzrgb" and coloured.data[12:] == bytes([1, 0, 255, 0])


def test_typed_calls_and_errors(server):
    client = NpfkctClient(server.url)
    session = client.create_session(world_of("covered1"), planner="kct", particles=50,
                                    options={"k": 4, "search.maxDepth": 8}, seed=5,
                                    display_name="typed", target_description="blue snack box")
    assert session.state == "READY"
    assert session.raw["planner"]["options"] == {"k": 4, "search.maxDepth": 8}
    assert [s.id for s in client.list_sessions(page_size=1)] == [session.id]
    plan = client.plan(session.id, simulations=300)
    assert plan.stats["simulations"] == 300
    with pytest.raises(ApiError) as e:
        client.plan(session.id, simulations=10)
    assert e.value.status == "FAILED_PRECONDITION"
    detection = Detection("box-1", Box([1.4, 0.1, 0.82], [0.12, 0.12, 0.14]), 0.9,
                          [Face(0, 0.2), Face(2, 0.1)])
    observed = client.observe(session.id, plan.action_id, robot_state=RobotConfig(x=0.3, tilt=0.4),
                              detections=[detection])
    assert observed.session.object_count == 1
    belief = client.belief(session.id)
    assert belief["objects"][0]["id"] == "box-1"
    assert client.belief_png(session.id)[:4] == b"\x89PNG"
    with pytest.raises(ApiError) as e:
        client.create_session({"furniture": [], "baseRegions": []})
    assert e.value.http_status == 400 and e.value.field.startswith("world")
    with pytest.raises(ApiError) as e:
        client.get_session("0" * 32)
    assert e.value.status == "NOT_FOUND"
    client.delete_session(session.id)
    assert client.list_sessions() == []


def test_the_client_installs_with_pip_and_runs_as_a_command(server, tmp_path):
    """clients/python installs into a virtual environment with pip, offline (Debian's
    python3-venv, python3-setuptools, python3-wheel and python3-requests: no package index), and
    its console script and `python3 -m npfkct_client` talk to the real server."""
    source = tmp_path / "src"  # a copy: setuptools writes build/ and *.egg-info beside it
    shutil.copytree(os.path.join(ROOT, "clients", "python"), source,
                    ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)],
                   check=True, timeout=120)
    pip = subprocess.run([str(venv / "bin" / "pip"), "install", "--no-build-isolation",
                          "--no-deps", "--no-index", "--disable-pip-version-check", str(source)],
                         capture_output=True, text=True, timeout=300)
    assert pip.returncode == 0, pip.stdout + pip.stderr
    command = str(venv / "bin" / "npfkct-client")
    helptext = subprocess.run([command, "--help"], capture_output=True, text=True, check=True,
                              timeout=60, cwd=tmp_path).stdout
    assert "create" in helptext and "--server" in helptext
    version = subprocess.run([command, "--version"], capture_output=True, text=True, check=True,
                             timeout=60, cwd=tmp_path).stdout
    assert version.strip() == "npfkct-client 0.1.0"
    created = subprocess.run([command, "--server", server.url, "create", "--scenario",
                              os.path.join(SCENARIOS, "hidden1.json"), "--seed", "4"],
                             capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert created.returncode == 0, created.stderr
    session = json.loads(created.stdout)
    # The module runs without PYTHONPATH from anywhere once installed.
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    got = subprocess.run([str(venv / "bin" / "python"), "-m", "npfkct_client", "--server",
                          server.url, "get", session["id"]], capture_output=True, text=True,
                         timeout=60, cwd=tmp_path, env=env)
    assert got.returncode == 0, got.stderr
    assert json.loads(got.stdout)["id"] == session["id"]


def test_the_readmes_sdk_block_runs_as_written(server):
    """The README's five-call loop, as pasted into python3 at the repository's root with the
    server named by NPFKCT_SERVER: the session is deleted when its with block ends, and a plan
    started with plan_async and cancelled leaves nothing behind."""
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        block = re.search(r"<!-- sdk -->\n```python\n(.*?)\n```", f.read(), re.S).group(1)
    env = dict(os.environ, NPFKCT_SERVER=server.url,
               PYTHONPATH=os.path.join(ROOT, "clients", "python"))
    env.pop("NPFKCT_API_KEY", None)
    out = subprocess.run([sys.executable, "-c", block], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    kind, value, simulations, done = out.stdout.split()
    assert kind in ("MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE")
    assert float(value) > 0 and int(simulations) > 0 and done == "False"
    assert NpfkctClient(server.url).list_sessions() == []


def server_cpu_seconds(server):
    """User and system CPU time of the server process so far."""
    with open(f"/proc/{server.proc.pid}/stat", encoding="ascii") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_session_objects_and_plan_async_cancel(server):
    """Session objects: plan, observe, refresh and delete on the session; plan_async returns a
    future; its cancel() stops the server's search within 100 ms of the server's CPU time (a
    60 s CPU budget otherwise), after which the session plans again."""
    client = NpfkctClient(server.url)
    with client.create_session(World.from_scenario(os.path.join(SCENARIOS, "loose1.json")),
                               planner="npfkct", seed=2) as s:
        first = s.plan(simulations=200)
        assert first.stats.simulations == 200 and first.stats["simulations"] == 200
        assert first.value == first.expected_value and first.session.state == "ACTION_PENDING"
        assert s.refresh().pending_action_id == first.action_id
        s.observe(first.action_id, robot_state=first.action.configuration or RobotConfig(),
                  detections=[])
        before = server_cpu_seconds(server)
        future = s.plan_async(cpu_ms=60000)
        # The search is under way once the server has spent 0.3 s of CPU on it.
        deadline = time.monotonic() + 60
        while server_cpu_seconds(server) - before < 0.3:
            assert not future.done() and time.monotonic() < deadline
            time.sleep(0.01)
        assert future.cancel()
        cancelled_at = server_cpu_seconds(server)
        with pytest.raises(concurrent.futures.CancelledError):
            future.result(timeout=30)
        assert future.cancelled() and future.done() and not future.cancel()
        # The server stops: its CPU time grows by less than 100 ms from the cancel on.
        settled, last = time.monotonic() + 30, -1.0
        while time.monotonic() < settled:
            now = server_cpu_seconds(server)
            if now == last:
                break
            last = now
            time.sleep(0.5)
        assert last - cancelled_at < 0.1, last - cancelled_at
        # No action is pending: the session plans again (ABORTED while the server lets go).
        for _ in range(100):
            try:
                again = s.plan(simulations=50)
                break
            except ApiError as e:
                assert e.status == "ABORTED", e
                time.sleep(0.05)
        assert again.stats.simulations == 50
        # A future that finished cannot be cancelled, and gives its plan.
        s.observe(again.action_id, robot_state=again.action.configuration or RobotConfig(),
                  detections=[])
        done = s.plan_async(simulations=20)
        assert done.result(timeout=60).stats.simulations == 20 and not done.cancel()
        name = s.id
    assert client.list_sessions() == []
    with pytest.raises(ApiError) as e:
        client.get_session(name)
    assert e.value.status == "NOT_FOUND"
    s.delete()  # twice: no error


def test_the_ros_nodes_episode_runs_without_ros(server):
    """npfkct_ros.episode (the ROS node's session and step loop, plain Python): a robot front of
    a few lines, here the simulated robot, finds the target in Loose1, each step heard once; the
    robot's reported MOVE counts as executed only where its base reached the goal."""
    sys.path.insert(0, os.path.join(ROOT, "clients", "ros", "npfkct_ros", "src"))
    try:
        from npfkct_ros.episode import Episode, Robot
        from npfkct_ros.retry import RetryPolicy
    finally:
        sys.path.pop(0)

    class SimulatedRobot(Robot):
        def __init__(self):
            self.sim, self.reply, self.logs = SimRobot("loose1", seed=4), None, []

        def now(self):
            return time.monotonic()

        def execute(self, action, sent):
            self.reply = self.sim.execute(action)
            return self.reply["observation"]["succeeded"]

        def observe(self, sent):
            seen = self.reply["observation"]
            return seen["robotState"], seen.get("detections", [])

        def sleep(self, seconds):
            time.sleep(seconds)

        def log(self, level, message):
            self.logs.append((level, message))

    robot = SimulatedRobot()
    steps = []
    try:
        episode = Episode(NpfkctClient(server.url), RetryPolicy(), robot)
        session = episode.create(World.from_scenario(os.path.join(SCENARIOS, "loose1.json")),
                                 seed=4)
        success, count, reward, message = episode.run(
            250, 50, lambda step, *rest: steps.append(step))
        assert success and message.startswith("target removed"), (message, robot.logs)
        assert steps == list(range(1, count + 1)) and reward > 5e4
        assert NpfkctClient(server.url).get_session(session.id).state == "DONE"
        episode.delete("test over")
        assert NpfkctClient(server.url).list_sessions() == []
    finally:
        robot.sim.close()

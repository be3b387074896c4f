"""kill -9 mid-episode: the restarted server finishes the episode with the same belief."""

import requests

from conftest import ServerProcess, SimRobot, world_of


def test_sigkill_mid_episode_loses_no_acknowledged_observation(tmp_path):
    state = str(tmp_path / "state")
    server = ServerProcess("--state-dir", state)
    url = server.url
    session = requests.post(url + "/v1/sessions", json={"world": world_of("covered1"), "seed": 4,
                                                         "planner": {"name": "npfkct"}}).json()
    sid = session["id"]
    robot = SimRobot("covered1", seed=4)
    steps, done = 0, False

    def step(url, plan=None):
        nonlocal steps, done
        if plan is None:
            plan = requests.post(url + f"/v1/sessions/{sid}:plan",
                                 json={"budget": {"timeMs": 200}}).json()
        reply = robot.execute(plan["action"])
        body = dict(reply["observation"], actionId=plan["actionId"])
        r = requests.post(url + f"/v1/sessions/{sid}:observe", json=body)
        assert r.status_code == 200, r.text
        steps += 1
        done = r.json()["done"]

    for _ in range(3):
        step(url)
    # An acknowledged observation, then a plan whose action is pending (the belief shows it as
    # the next view), then kill -9.
    pending = requests.post(url + f"/v1/sessions/{sid}:plan",
                            json={"budget": {"timeMs": 200}}).json()
    belief = requests.get(url + f"/v1/sessions/{sid}/belief").json()
    server.kill()

    server = ServerProcess("--state-dir", state)
    url = server.url
    assert requests.get(url + f"/v1/sessions/{sid}/belief").json() == belief
    resumed = requests.get(url + f"/v1/sessions/{sid}").json()
    assert resumed["state"] == "ACTION_PENDING"
    assert resumed["pendingAction"]["actionId"] == pending["actionId"]
    assert resumed["pendingAction"]["action"] == pending["action"]
    step(url, plan=pending)
    while not done and steps < 50:
        step(url)
    robot.close()
    assert done, f"the target was not removed within {steps} steps"
    server.stop()


def cube_on_table(edge=0.12):
    """Points 1 cm apart on the top and sides of a cube standing on the example world's table,
    in the map frame: one perception track."""
    n, points = int(edge / 0.01), []
    x0, y0, z0 = 1.5 - edge / 2, 0.1 - edge / 2, 0.75
    for i in range(n + 1):
        for k in range(n + 1):
            u, v = i * edge / n, k * edge / n
            points += [(x0 + u, y0 + v, z0 + edge), (x0 + u, y0, z0 + v), (x0, y0 + u, z0 + v),
                       (x0 + u, y0 + edge, z0 + v), (x0 + edge, y0 + u, z0 + v)]
    return points


def test_perception_tracks_are_restored_when_a_frame_needs_them(tmp_path):
    """A restored session keeps its perception tracks as stored and builds its perception (the
    prior map of the whole room: seconds of CPU in a large one) only when a raw frame needs it:
    the tracks survive restarts in between, and the frame after them finds the same object."""
    from test_hostile import example, raw_observation
    state = str(tmp_path / "state")
    server = ServerProcess("--state-dir", state)
    body = dict(example("create_session_request.json"), planner={"name": "kct", "particles": 50})
    sid = requests.post(server.url + "/v1/sessions", json=body).json()["id"]

    def step(url, raw):
        action_id = requests.post(f"{url}/v1/sessions/{sid}:plan",
                                  json={"budget": {"simulations": 20}}).json()["actionId"]
        observation = raw_observation(action_id, cube_on_table(), "map")
        if not raw:
            observation = {"actionId": action_id, "detections": [],
                           "robotState": observation["robotState"]}
        r = requests.post(f"{url}/v1/sessions/{sid}:observe", json=observation)
        assert r.status_code == 200, r.text
        return r.json()["session"]

    assert step(server.url, raw=True)["perceptionTracks"] == 1
    objects = requests.get(f"{server.url}/v1/sessions/{sid}").json()["objectCount"]
    for _ in range(2):  # restarted, then saved without a raw frame, then restarted again
        server.stop()
        server = ServerProcess("--state-dir", state)
        assert requests.get(f"{server.url}/v1/sessions/{sid}").json()["perceptionTracks"] == 1
        step(server.url, raw=False)
    seen = step(server.url, raw=True)
    assert seen["perceptionTracks"] == 1 and seen["objectCount"] == objects, seen
    server.stop()

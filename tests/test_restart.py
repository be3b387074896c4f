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

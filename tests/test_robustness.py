"""10,000 malformed or hostile requests: no crash, no 5xx, and the sessions stay intact.

CI runs this file a second time against an AddressSanitizer build of the server
(NPFKCT_SERVER_BIN, see scripts/test.sh)."""

import concurrent.futures
import copy
import json
import os
import random
import socket

import requests

from conftest import ServerProcess, SimRobot, world_of

REQUESTS = int(os.environ.get("NPFKCT_ROBUSTNESS_REQUESTS", "10000"))

HOSTILE_VALUES = [None, True, False, 0, -1, 1e308, -1e308, 2**63, -(2**63), 1.5, "", "x" * 5000,
                  "NaN", [], {}, [1e400], {"$ref": "#"}, "\u0000", "💥", [[[[[]]]]], "1e999"]


def mutate(value, rng, depth=0):
    """A random mutation of a JSON value: drop/add keys, swap types, hostile numbers."""
    if isinstance(value, dict) and value and rng.random() < 0.8:
        out = dict(value)
        key = rng.choice(list(out))
        choice = rng.random()
        if choice < 0.25:
            del out[key]
        elif choice < 0.5:
            out[key] = rng.choice(HOSTILE_VALUES)
        elif choice < 0.6:
            out["unexpected" + str(rng.randint(0, 9))] = rng.choice(HOSTILE_VALUES)
        else:
            out[key] = mutate(out[key], rng, depth + 1)
        return out
    if isinstance(value, list) and value and rng.random() < 0.8:
        out = list(value)
        i = rng.randrange(len(out))
        choice = rng.random()
        if choice < 0.3:
            del out[i]
        elif choice < 0.6:
            out[i] = rng.choice(HOSTILE_VALUES)
        else:
            out[i] = mutate(out[i], rng, depth + 1)
        return out
    return rng.choice(HOSTILE_VALUES)


def raw_body(rng, valid):
    """A request body: a mutated valid body, or broken JSON, NaN, deep nesting, huge numbers."""
    kind = rng.random()
    if kind < 0.6:
        return json.dumps(mutate(copy.deepcopy(valid), rng))
    if kind < 0.7:
        text = json.dumps(valid)
        cut = rng.randrange(len(text)) if text else 0
        return text[:cut]
    if kind < 0.75:
        return json.dumps(valid).replace("0.", "NaN", 1).replace("1", "Infinity", 1)
    if kind < 0.8:
        depth = rng.choice([10, 70, 1000, 100000])
        return "[" * depth + "]" * depth
    if kind < 0.85:
        return '{"budget": {"timeMs": 1' + "0" * rng.randint(20, 400) + "}}"
    if kind < 0.9:
        return bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 300))).decode("latin-1")
    return rng.choice(["null", "[]", "\"string\"", "42", "{}", " ", "{\"a\":"])


def test_hostile_requests(tmp_path):
    server = ServerProcess("--max-body-mb", "1", "--default-plan-ms", "20", "--max-plan-ms", "50",
                           "--threads", "8",
                           "--state-dir", str(tmp_path / "state"))
    url = server.url
    rng = random.Random(1234)
    world = world_of("loose1")
    create = {"world": world, "seed": 1, "planner": {"name": "npfkct", "particles": 50}}
    keeper = requests.post(url + "/v1/sessions", json=create).json()["id"]
    victims = [requests.post(url + "/v1/sessions", json=create).json()["id"] for _ in range(4)]
    observe = {"actionId": "a1-000000", "robotState": {"x": 0.3, "y": 0, "yaw": 0, "lift": 0.2,
                                                       "pan": 0, "tilt": 0.4},
               "detections": [{"id": "b", "box": {"center": [1.4, 0, 0.8], "size": [0.1, 0.1, 0.1]},
                               "faces": [{"corner": 1, "score": 0.3}]}]}
    plan = {"budget": {"timeMs": 5, "simulations": 50}}
    bodies = {"/v1/sessions": create, ":plan": plan, ":observe": observe}

    def one(i):
        r = random.Random(i)
        target = r.choice(["create", "plan", "observe", "get", "delete", "belief", "list",
                           "unknown", "oversize", "method"])
        sid = r.choice(victims + ["0" * 32, "not-an-id", "../../etc/passwd", "%00", "x" * 300])
        try:
            if target == "create":
                resp = requests.post(url + "/v1/sessions", data=raw_body(r, create), timeout=60)
            elif target == "plan":
                resp = requests.post(url + f"/v1/sessions/{sid}:plan", data=raw_body(r, plan),
                                     timeout=60)
            elif target == "observe":
                resp = requests.post(url + f"/v1/sessions/{sid}:observe",
                                     data=raw_body(r, observe), timeout=60)
            elif target == "get":
                resp = requests.get(url + f"/v1/sessions/{sid}", timeout=60)
            elif target == "delete":
                resp = requests.delete(url + f"/v1/sessions/{sid}", timeout=60)
            elif target == "belief":
                resp = requests.get(url + f"/v1/sessions/{sid}/belief",
                                    params={"format": r.choice(["json", "png", "gif", ""])},
                                    timeout=60)
            elif target == "list":
                resp = requests.get(url + "/v1/sessions",
                                    params={"pageSize": r.choice(["1", "0", "-5", "99999", "x"]),
                                            "pageToken": r.choice(["", "zz", "0" * 32])},
                                    timeout=60)
            elif target == "oversize":
                resp = requests.post(url + "/v1/sessions", data="{" + " " * (2 << 20) + "}",
                                     timeout=60)
            elif target == "unknown":
                resp = requests.get(url + r.choice(["/", "/v1", "/v1/sessions/x/y/z",
                                                    "/v1/sessions:plan", "/metricsx"]), timeout=60)
            else:
                resp = requests.request(r.choice(["PUT", "PATCH", "OPTIONS"]),
                                        url + "/v1/sessions", data="{}", timeout=60)
            return resp.status_code, resp.text
        except requests.exceptions.ConnectionError as e:
            return -1, str(e)

    with concurrent.futures.ThreadPoolExecutor(max_workers=16) as pool:
        results = list(pool.map(one, range(REQUESTS)))
    # Requests that HTTP cannot express reach the server as raw bytes; the server may answer or
    # wait for more, but must survive.
    for raw in [b"GET / HTTP/1.1\r\n\r\n", b"\x00\x01\x02garbage\r\n\r\n",
                b"POST /v1/sessions HTTP/1.1\r\nContent-Length: 999999999999\r\n\r\n{}",
                b"POST /v1/sessions HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n"]:
        with socket.create_connection(("127.0.0.1", server.port), timeout=2) as s:
            s.sendall(raw)
            try:
                s.recv(4096)
            except socket.timeout:
                pass

    assert server.alive(), "the server crashed"
    codes = [c for c, _ in results]
    assert -1 not in codes, [t for c, t in results if c == -1][:3]
    fivexx = [(c, t) for c, t in results if c >= 500]
    assert not fivexx, fivexx[:5]
    for code, text in results:
        if code >= 400:
            body = json.loads(text)
            assert set(body["error"]) == {"code", "status", "message", "details"}

    # The untouched session still works end to end.
    r = requests.post(url + f"/v1/sessions/{keeper}:plan", json={"budget": {"simulations": 100}})
    assert r.status_code == 200, r.text
    action = r.json()
    robot = SimRobot("loose1")
    body = dict(robot.execute(action["action"])["observation"], actionId=action["actionId"])
    robot.close()
    assert requests.post(url + f"/v1/sessions/{keeper}:observe", json=body).status_code == 200
    # Every surviving session is readable and consistent.
    for s in requests.get(url + "/v1/sessions", params={"pageSize": 1000}).json()["sessions"]:
        assert requests.get(url + f"/v1/sessions/{s['id']}/belief").status_code == 200
    server.stop()

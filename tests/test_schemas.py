"""JSON Schemas (draft 2020-12) and the OpenAPI document: examples and real responses validate."""

import base64
import json
import os

import jsonschema
import pytest
import requests
import yaml

from conftest import ROOT, SimRobot, world_of

SCHEMAS = os.path.join(ROOT, "schemas")
# The schemas' $ids are relative (their file names): a reference resolves to the file beside the
# referring one, wherever the folder is served or read from.
BASE = "file://" + SCHEMAS + "/"


def load(name):
    with open(os.path.join(SCHEMAS, name), encoding="utf-8") as f:
        return json.load(f)


def store():
    return {BASE + f: load(f) for f in os.listdir(SCHEMAS) if f.endswith(".schema.json")}


def validator(message):
    schema = load(message + ".schema.json")
    resolver = jsonschema.RefResolver(base_uri=BASE + schema["$id"], referrer=schema,
                                      store=store())
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema, resolver=resolver, format_checker=jsonschema.FormatChecker())


def test_every_schema_is_valid_draft_2020_12():
    for name in os.listdir(SCHEMAS):
        if name.endswith(".schema.json"):
            schema = load(name)
            assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
            assert schema["$id"] == name  # relative: no host that would have to answer
            jsonschema.Draft202012Validator.check_schema(schema)


def test_examples_validate():
    examples = os.listdir(os.path.join(SCHEMAS, "examples"))
    assert len(examples) >= 14
    for name in examples:
        message = name[: -len(".json")]
        for variant in ("_raw", "_boxes"):  # raw sensor data, and with a detector's boxes
            if message.endswith(variant):
                message = message[: -len(variant)]
        with open(os.path.join(SCHEMAS, "examples", name), encoding="utf-8") as f:
            validator(message).validate(json.load(f))


def test_schemas_reject_what_the_server_rejects():
    with pytest.raises(jsonschema.ValidationError):
        validator("observe_request").validate(
            {"actionId": "a1", "detections": [{"id": "x", "box": {"center": [0, 0], "size": [1, 1, 1]}}]})
    with pytest.raises(jsonschema.ValidationError):  # detections and raw data together
        validator("observe_request").validate(
            {"actionId": "a1", "detections": [], "pointCloud": {"data": "AAAA"}})
    with pytest.raises(jsonschema.ValidationError):  # an image without its cloud
        validator("observe_request").validate({"actionId": "a1", "image": {"data": "AAAA"}})
    with pytest.raises(jsonschema.ValidationError):
        validator("plan_request").validate({"budget": {"timeMs": -1}})
    with pytest.raises(jsonschema.ValidationError):
        validator("create_session_request").validate({"world": {"furniture": []}})


def test_openapi_document_references_resolve():
    with open(os.path.join(SCHEMAS, "openapi.yaml"), encoding="utf-8") as f:
        doc = yaml.safe_load(f)
    assert doc["openapi"].startswith("3.1")
    assert {"/v1/sessions", "/v1/sessions/{id}", "/v1/sessions/{id}:plan",
            "/v1/sessions/{id}:observe", "/v1/sessions/{id}/belief", "/v1/sessions/{id}/steps",
            "/healthz", "/metrics"} <= set(doc["paths"])
    refs = []

    def walk(node):
        if isinstance(node, dict):
            if "$ref" in node and not node["$ref"].startswith("#"):
                refs.append(node["$ref"])
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)
    walk(doc)
    assert refs
    for ref in refs:
        assert os.path.exists(os.path.join(SCHEMAS, ref)), ref


def test_real_responses_validate(server):
    url = server.url
    v = lambda m, body: validator(m).validate(body)  # noqa: E731
    v("health", requests.get(url + "/healthz").json())
    create = {"world": world_of("hidden1"), "seed": 9, "planner": {"name": "npfkct"}}
    v("create_session_request", create)
    session = requests.post(url + "/v1/sessions", json=create).json()
    v("session", session)
    robot = SimRobot("hidden1", seed=9)
    for _ in range(3):
        plan = requests.post(url + f"/v1/sessions/{session['id']}:plan",
                             json={"budget": {"timeMs": 100}}).json()
        v("plan_response", plan)
        body = dict(robot.execute(plan["action"])["observation"], actionId=plan["actionId"])
        v("observe_request", body)
        observed = requests.post(url + f"/v1/sessions/{session['id']}:observe", json=body).json()
        v("observe_response", observed)
        if observed["done"]:
            break
    robot.close()
    # Raw frames through perception.
    raw_robot = SimRobot("hidden1", seed=9, raw=True)
    raw_create = {"world": world_of("hidden1"), "seed": 9,
                  "target": {"photos": [base64.b64encode(p).decode()
                                        for p in raw_robot.target_photos()]}}
    v("create_session_request", raw_create)
    raw_session = requests.post(url + "/v1/sessions", json=raw_create).json()
    v("session", raw_session)
    perceived = 0
    for _ in range(3):
        plan = requests.post(url + f"/v1/sessions/{raw_session['id']}:plan",
                             json={"budget": {"timeMs": 100}}).json()
        body = dict(raw_robot.execute(plan["action"])["observation"], actionId=plan["actionId"])
        v("observe_request", body)
        observed = requests.post(url + f"/v1/sessions/{raw_session['id']}:observe",
                                 json=body).json()
        v("observe_response", observed)
        perceived += "perception" in observed
        if observed["done"]:
            break
    raw_robot.close()
    assert perceived > 0
    v("session", requests.get(url + f"/v1/sessions/{raw_session['id']}").json())
    v("belief", requests.get(url + f"/v1/sessions/{session['id']}/belief").json())
    steps = requests.get(url + f"/v1/sessions/{session['id']}/steps").json()
    v("steps_response", steps)
    assert [s["step"] for s in steps["steps"]] == list(range(1, len(steps["steps"]) + 1))
    assert steps["steps"] and all("outcome" in s for s in steps["steps"])  # every step observed
    v("list_sessions_response", requests.get(url + "/v1/sessions").json())
    for bad in [("post", f"/v1/sessions/{session['id']}:plan", {"budget": {"simulations": -1}}),
                ("get", "/v1/sessions/" + "f" * 32, None), ("post", "/v1/sessions", {"x": 1})]:
        r = getattr(requests, bad[0])(url + bad[1], json=bad[2])
        assert r.status_code >= 400
        v("error", r.json())
    v("empty", requests.delete(url + f"/v1/sessions/{session['id']}").json())


def test_planners_list_the_registry_and_plans_report_the_options_they_used(server):
    """GET /v1/planners lists the planners the schema's PlannerSpec.name allows, with every
    option's default; a plan's summary gives the options given and every option as used: the
    defaults with the given ones applied."""
    url = server.url
    planners = requests.get(url + "/v1/planners").json()
    validator("list_planners_response").validate(planners)
    names = [p["name"] for p in planners["planners"]]
    assert names == load("common.schema.json")["$defs"]["PlannerSpec"]["properties"]["name"][
        "enum"]
    by_name = {p["name"]: p for p in planners["planners"]}
    assert by_name["npfkct"]["takesModel"] and not by_name["kct"]["takesModel"]
    assert by_name["npfkct"]["defaults"]["search.maxDepth"] == 12
    assert "filter.candidates" in by_name["npfkct"]["defaults"]
    assert "filter.candidates" not in by_name["kct"]["defaults"]
    given = {"search.maxDepth": 8, "k": 4}
    session = requests.post(url + "/v1/sessions", json={
        "world": world_of("loose1"), "seed": 5,
        "planner": {"name": "kct", "particles": 50, "options": given}}).json()
    plan = requests.post(url + f"/v1/sessions/{session['id']}:plan",
                         json={"budget": {"simulations": 50}}).json()
    validator("plan_response").validate(plan)
    summary = plan["summary"]
    assert summary["optionsGiven"] == given
    assert summary["optionsUsed"] == {**by_name["kct"]["defaults"], **given}
    assert summary["budgetGiven"] == {"timeMs": 0, "cpuMs": 0, "simulations": 50}
    assert plan["budget"]["simulations"] == 50 and plan["budget"]["timeMs"] > 0
    assert {"w2", "cR", "threads"} <= set(summary["resolved"])
    requests.delete(url + f"/v1/sessions/{session['id']}")

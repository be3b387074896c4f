"""The curl scripts: a full episode with curl only, and errors surfacing as failures."""

import json
import os
import subprocess

from conftest import ROBOT_BIN, ROOT, scenario_path

CURL = os.path.join(ROOT, "clients", "curl")


def run(script, *args, server):
    env = dict(os.environ, NPFKCT_SERVER=server.url)
    return subprocess.run([os.path.join(CURL, script), *args], env=env, capture_output=True,
                          text=True, timeout=300)


def test_full_episode_with_curl(server):
    r = run("episode.sh", scenario_path("loose1"), ROBOT_BIN, "250", server=server)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "outcome: target removed" in r.stdout


def test_scripts_report_errors(server, tmp_path):
    assert json.loads(run("health.sh", server=server).stdout)["status"] == "SERVING"
    missing = run("get_session.sh", "0" * 32, server=server)
    assert missing.returncode != 0
    assert json.loads(missing.stdout)["error"]["status"] == "NOT_FOUND"
    body = tmp_path / "bad.json"
    body.write_text('{"world": {"furniture": "table"}}')
    bad = run("create_session.sh", str(body), server=server)
    assert bad.returncode != 0
    error = json.loads(bad.stdout)["error"]
    assert error["details"][0]["fieldViolations"][0]["field"] == "world.furniture"
    assert "npfkct_sessions" in run("metrics.sh", server=server).stdout
    assert json.loads(run("list_sessions.sh", server=server).stdout) == {"sessions": []}

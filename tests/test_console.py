"""The web console in a real browser: Debian's Chromium, headless, driven by playwright-core
(tests/js/console_check.mjs), watches a session while the simulated robot plays an episode
against the same server. The server runs with --api-key: the page must ask for it. The
screenshots land in BUILD/console-screenshots (docs/pictures/ holds copies of them)."""

import json
import os
import shutil
import subprocess
import threading

import pytest

from conftest import BUILD, ROOT, ServerProcess, SimRobot, npm_tool, world_of
from npfkct_client import NpfkctClient

KEY = "console-test-key"
SHOTS = os.path.join(BUILD, "console-screenshots")


def chromium():
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("chromium is not installed (scripts/deps.sh installs Debian's chromium)")


def play(client, session_id, robot, steps, stop, errors):
    """The robot's loop, paced so that the page sees the steps arrive one by one."""
    try:
        for _ in range(steps):
            if stop.is_set():
                return
            plan = client.plan(session_id, time_ms=300)
            reply = robot.execute(plan.action.to_json())
            observed = client.observe(session_id, plan.action_id, body=reply["observation"])
            if observed.done:
                return
            stop.wait(1.5)
    except Exception as e:  # reported by the test
        errors.append(e)


def test_the_console_shows_a_live_episode():
    tool = npm_tool(os.path.join(ROOT, "tests", "js"), "js-tools")
    os.makedirs(SHOTS, exist_ok=True)
    server = ServerProcess("--api-key", KEY)
    client = NpfkctClient(server.url, api_key=KEY)
    session = client.create_session(world_of("loose1"), seed=5, display_name="console test")
    robot = SimRobot("loose1", seed=5)
    stop, errors = threading.Event(), []
    player = threading.Thread(target=play, args=(client, session.id, robot, 30, stop, errors))
    try:
        # The page first asks for the key; the robot starts once the page has opened the session
        # (the check prints "watching"), so that the page sees the episode's steps arrive: a
        # robot started with the browser finished Loose1 before a slow first Chromium start
        # showed the page (it saw step 4 first and no later one).
        browser = subprocess.Popen(
            ["node", os.path.join(tool, "console_check.mjs"), server.url, KEY, SHOTS, "3"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "CHROMIUM": chromium()})
        watchdog = threading.Timer(180, browser.kill)
        watchdog.start()
        head = []
        for line in browser.stdout:
            head.append(line)
            if line.strip() == "watching":
                break
        watchdog.cancel()
        player.start()
        out, err = browser.communicate(timeout=400)
        out = "".join(head) + out
        assert browser.returncode == 0, err[-3000:]
        seen = json.loads(out.strip().splitlines()[-1])
    finally:
        stop.set()
        if player.is_alive():
            player.join(timeout=120)
        robot.close()
        server.stop()
    assert not errors, errors
    assert seen["askedForKey"] and seen["refusedWrongKey"]
    assert seen["stepsWhileWatching"][1] > seen["stepsWhileWatching"][0]
    assert seen["objectsLabelled"], "no object was labelled"
    assert seen["bestGuess"]
    assert seen["badFragmentListed"]
    for name in ("console-api-key.png", "console-episode.png", "console-done.png"):
        assert os.path.getsize(os.path.join(SHOTS, name)) > 10_000, name

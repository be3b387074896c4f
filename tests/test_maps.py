"""A prior map from SLAM: a ROS map_server map (YAML + PGM) as the session's occupancy grid, the
workspaces traced as polygons with their heights, the base regions placed around them; bad grids
and polygons get 400s naming the field."""

import base64
import json
import math
import os
import subprocess
import sys

import pytest
import requests

from conftest import ROOT, SimRobot, world_of
from npfkct_client import (NpfkctClient, occupancy_grid_from_map_files, slam_world,
                           traced_workspaces, write_map_files)

TABLE = [[1.0, -0.4], [2.2, -0.4], [2.2, 0.4], [1.0, 0.4]]  # Loose1's table, x 1.0-2.2, y +-0.4


def write_loose1_map(directory):
    """Loose1's room rasterised as map_server writes it (npfkct_client.write_map_files: walls on
    the border and the table's footprint occupied, black; the floor free), and five unknown
    cells (205) at the start of the PGM's first row, the highest y."""
    path = write_map_files(world_of("loose1"), directory, "loose1")
    pgm = os.path.join(directory, "loose1.pgm")
    with open(pgm, "rb") as f:
        data = bytearray(f.read())
    header = len(b"P5\n140 130\n255\n")
    assert data[:header] == b"P5\n140 130\n255\n"
    data[header:header + 5] = bytes([205] * 5)
    with open(pgm, "wb") as f:
        f.write(bytes(data))
    return path


def map_world(yaml_path):
    """Loose1's world from the map files: the grid, the table traced, no base regions."""
    return slam_world(world_of("loose1"), yaml_path)


def test_the_map_files_read_as_the_occupancy_grid(tmp_path):
    grid = occupancy_grid_from_map_files(write_loose1_map(str(tmp_path)))
    assert (grid["width"], grid["height"], grid["resolution"]) == (140, 130, 0.05)
    assert grid["origin"] == [-3.0, -3.0, 0.0]
    cells = base64.b64decode(grid["data"])
    assert len(cells) == 140 * 130
    at = lambda x, y: cells[int((y + 3.0) / 0.05) * 140 + int((x + 3.0) / 0.05)]
    assert at(1.6, 0.0) == 100 and at(-1.0, 0.0) == 0 and at(-2.99, -2.99) == 100
    assert cells[(130 - 1) * 140 + 2] == 0xFF  # the PGM's top-left corner: unknown, the top row
    traced = traced_workspaces(world_of("loose1"))
    assert [(w["name"], w["height"]) for w in traced] == [("table", 0.75)]
    assert [v for p in traced[0]["polygon"] for v in p] == pytest.approx(
        [v for p in TABLE for v in p])


def test_a_session_on_a_slam_map_finds_the_target(server, tmp_path):
    client = NpfkctClient(server.url)
    world = map_world(write_loose1_map(str(tmp_path)))
    session = client.create_session(world, seed=2)
    belief = client.belief(session.id)
    assert len(belief["furniture"]) == 1
    table = belief["furniture"][0]  # the box around the traced polygon
    assert sorted(table["size"][:2]) == pytest.approx([0.8, 1.2])
    assert table["center"][:2] == pytest.approx([1.6, 0.0])
    # Four strips around the table, from the footprint (0.3 m) plus clearance (0.05 m) to the
    # reach (1 m): the left one is x in [0.0, 0.65].
    assert len(belief["baseRegions"]) == 4
    assert belief["baseRegions"][0]["min"][0] == pytest.approx(0.0)
    assert belief["baseRegions"][0]["max"][0] == pytest.approx(0.65)
    robot = SimRobot("loose1", seed=2)
    try:
        for _ in range(30):
            plan = client.plan(session.id, simulations=500)
            if plan.action.type == "MOVE":  # the base stands where the map is free
                c = plan.action.configuration
                assert any(r["min"][0] <= c.x <= r["max"][0] and r["min"][1] <= c.y <= r["max"][1]
                           for r in belief["baseRegions"])
            reply = robot.execute(plan.action.to_json())
            observed = client.observe(session.id, plan.action_id, body=reply["observation"])
            if observed.done:
                break
        assert observed.done, "the target was not removed within 30 steps"
    finally:
        robot.close()
        client.delete_session(session.id)


def test_the_command_line_client_takes_a_map(server, tmp_path):
    yaml_path = write_loose1_map(str(tmp_path))
    out = subprocess.run([sys.executable, "-m", "npfkct_client", "--server", server.url, "create",
                          "--scenario", os.path.join(ROOT, "scenarios", "loose1.json"),
                          "--map", yaml_path], capture_output=True, text=True, timeout=60,
                         env=dict(os.environ, PYTHONPATH=os.path.join(ROOT, "clients", "python")))
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["state"] == "READY"


def test_bad_grids_and_polygons_name_their_field(server, tmp_path):
    world = map_world(write_loose1_map(str(tmp_path)))
    grid = world["occupancyGrid"]
    cases = [
        ({"occupancyGrid": dict(grid, width=2000, height=1000)}, "world.occupancyGrid.width"),
        ({"occupancyGrid": dict(grid, width=139)}, "world.occupancyGrid.data"),
        ({"occupancyGrid": dict(grid, origin=[-3.0, -3.0, 0.5])}, "world.occupancyGrid.origin[2]"),
        ({"occupancyGrid": dict(grid, data="@@@")}, "world.occupancyGrid.data"),
        ({"occupancyGrid": dict(grid, resolution=0)}, "world.occupancyGrid.resolution"),
        ({"room": {"min": [-3, -3], "max": [4, 3.5]}}, "world.room"),
        ({"workspaces": [{"name": "t", "polygon": [[0, 0], [1, 1], [2, 2]], "height": 0.7}]},
         "world.workspaces[0].polygon"),
        ({"workspaces": [{"name": "t", "polygon": TABLE[:2], "height": 0.7}]},
         "world.workspaces[0].polygon"),
        ({"workspaces": [{"name": f"t{i}", "polygon": [[x + i * 0.2 for x in p] for p in TABLE],
                          "height": 0.7} for i in range(17)]}, "world.baseRegions"),
        ({"workspaces": [], "furniture": []}, "world.furniture"),
        # Past the counts: 101 workspaces, a polygon of 65 points.
        ({"workspaces": [{"name": f"t{i}", "polygon": TABLE, "height": 0.7} for i in range(101)]},
         "world.workspaces"),
        ({"workspaces": [{"name": "t", "height": 0.7, "polygon": [
            [1.0 + 0.5 * math.cos(k * math.pi / 32.5), 0.5 * math.sin(k * math.pi / 32.5)]
            for k in range(65)]}]}, "world.workspaces[0].polygon"),
        # An outside check's finds: a map past the coordinates the API takes (its sessions were
        # planned beyond them and lost on restart), a side the belief picture cannot warp, a
        # cell value the message does not have, a workspace longer than any furniture, one off
        # the map.
        ({"occupancyGrid": dict(grid, origin=[9990.0, -50.0, 0.0], resolution=1.0, width=1000,
                                height=100, data=base64.b64encode(bytes(100000)).decode())},
         "world.occupancyGrid.width"),
        ({"occupancyGrid": dict(grid, width=32767, height=30,
                                data=base64.b64encode(bytes(32767 * 30)).decode())},
         "world.occupancyGrid.width"),
        ({"occupancyGrid": dict(grid, data=base64.b64encode(
            bytes([101]) + base64.b64decode(grid["data"])[1:]).decode())},
         "world.occupancyGrid.data"),
        ({"workspaces": [{"name": "long", "polygon": [[-20, 0], [5, 0], [5, 0.3], [-20, 0.3]],
                          "height": 0.7}]}, "world.workspaces[0].polygon"),
        ({"workspaces": [{"name": "far", "polygon": [[50, 50], [51, 50], [51, 51], [50, 51]],
                          "height": 0.7}]}, "world.baseRegions"),
    ]
    for edit, field in cases:
        body = {"world": dict(world, **edit)}
        r = requests.post(server.url + "/v1/sessions", json=body, timeout=30)
        assert r.status_code == 400, (field, r.text[:300])
        violations = r.json()["error"]["details"][0]["fieldViolations"]
        assert violations[0]["field"] == field, (field, r.text[:300])


def test_line_wrapped_base64_of_the_grid_is_read(server, tmp_path):
    """MIME-style base64 (a line break every 76 characters) of exactly width x height cells."""
    world = map_world(write_loose1_map(str(tmp_path)))
    cells = base64.b64decode(world["occupancyGrid"]["data"])
    world["occupancyGrid"]["data"] = base64.encodebytes(cells).decode()
    r = requests.post(server.url + "/v1/sessions", json={"world": world}, timeout=30)
    assert r.status_code == 200, r.text[:300]


def write_table_pcd(path, data="binary", top=0.75):
    """A point-cloud map of Loose1's table as PCL writes one (FIELDS x y z rgb): the floor
    around it, its top at `top` on a 1 cm grid, four legs, a box standing on it (0.75-0.9 m) and
    a NaN point; DATA binary or ascii."""
    import struct
    points = [(x / 100.0, y / 100.0, 0.0) for x in range(60, 260, 2) for y in range(-80, 80, 2)]
    points += [(x / 100.0, y / 100.0, top) for x in range(100, 221) for y in range(-40, 41)]
    points += [(cx, cy, z / 100.0) for cx in (1.05, 2.15) for cy in (-0.35, 0.35)
               for z in range(0, round(top * 100))]
    points += [(x / 100.0, y / 100.0, top + z / 100.0) for x in range(150, 161)
               for y in range(-5, 6) for z in range(0, 16)]
    points.append((float("nan"), 0.0, 0.0))
    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\n"
              "SIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
              f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\n"
              f"DATA {data}\n")
    with open(path, "wb") as f:
        f.write(header.encode())
        if data == "binary":
            f.write(b"".join(struct.pack("<fffI", x, y, z, 0x00808080) for x, y, z in points))
        else:
            f.write("".join(f"{x} {y} {z} 8421504\n" for x, y, z in points).encode())
    return len(points)


def test_the_workspaces_heights_come_from_a_point_cloud_map(server, tmp_path):
    """Workspaces traced without a height get the table top's from a PCD (binary or ascii), the
    box on the table and the legs notwithstanding; the command-line client sends them."""
    from npfkct_client import read_pcd, workspace_heights
    for data in ("binary", "ascii"):
        pcd = str(tmp_path / f"table_{data}.pcd")
        total = write_table_pcd(pcd, data)
        points = read_pcd(pcd)
        assert len(points) == total - 1  # the NaN point left out
        measured = workspace_heights([{"name": "table", "polygon": TABLE}], points)
        assert measured[0]["height"] == pytest.approx(0.75, abs=0.011)
    write_table_pcd(str(tmp_path / "low.pcd"), top=0.42)
    assert workspace_heights([{"name": "table", "polygon": TABLE}],
                             read_pcd(str(tmp_path / "low.pcd")))[0]["height"] == pytest.approx(
                                 0.42, abs=0.011)
    # Given heights are kept; a workspace the cloud does not reach is an error naming it.
    given = [{"name": "table", "polygon": TABLE, "height": 0.7}]
    assert workspace_heights(given, points) == given
    with pytest.raises(ValueError, match="workspace shelf"):
        workspace_heights([{"name": "shelf", "polygon": [[-2, -2], [-1, -2], [-1, -1]]}], points)
    # The command-line client: the map files, the workspaces without heights, the PCD.
    yaml_path = write_loose1_map(str(tmp_path))
    workspaces = tmp_path / "workspaces.json"
    workspaces.write_text(json.dumps([{"name": "table", "polygon": TABLE}]))
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "clients", "python"))
    command = [sys.executable, "-m", "npfkct_client", "--server", server.url, "create",
               "--scenario", os.path.join(ROOT, "scenarios", "loose1.json"), "--map", yaml_path,
               "--workspaces", str(workspaces)]
    out = subprocess.run(command + ["--pcd", str(tmp_path / "table_binary.pcd")],
                         capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0, out.stderr
    session = json.loads(out.stdout)
    assert session["state"] == "READY"
    belief = requests.get(f"{server.url}/v1/sessions/{session['id']}/belief", timeout=10)
    assert belief.status_code == 200, belief.text[:300]
    assert [w["height"] for w in belief.json()["grid"]["workspaces"]] == [
        pytest.approx(0.75, abs=0.011)]
    # Without the PCD, or with one PCL compressed, the client says why and sends nothing.
    out = subprocess.run(command, capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 2 and "point-cloud map" in out.stderr
    compressed = tmp_path / "compressed.pcd"
    compressed.write_bytes(b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                           b"WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary_compressed\n\0\0\0\0")
    out = subprocess.run(command + ["--pcd", str(compressed)], capture_output=True, text=True,
                         timeout=60, env=env)
    assert out.returncode == 2 and "binary_compressed" in out.stderr

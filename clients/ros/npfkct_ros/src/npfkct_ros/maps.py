"""The session's world from a SLAM map: a nav_msgs/OccupancyGrid (its fields, so that this
module needs no ROS) as the API's occupancyGrid, with the workspaces traced in the map."""

import base64
import math
import struct

from npfkct_ros.geometry import yaw_of


def occupancy_grid_json(msg):
    """The API's world.occupancyGrid from an OccupancyGrid message (info.resolution, width,
    height, origin; data int8 row by row from the origin, -1 unknown)."""
    info = msg.info
    data = struct.pack(f"<{len(msg.data)}b", *msg.data)
    return {"resolution": float(info.resolution),
            "origin": [float(info.origin.position.x), float(info.origin.position.y),
                       yaw_of(info.origin.orientation)],
            "width": int(info.width), "height": int(info.height),
            "data": base64.b64encode(data).decode()}


def world_from_map(base, grid, workspaces):
    """A session's world: the occupancy grid and the traced workspaces in place of the base
    world's room, furniture and base regions (the server places base regions around the
    workspaces); the base world (a scenario's, or {}) gives the robot, the start and the
    parameters."""
    if not workspaces:
        raise ValueError("a map needs workspaces: set ~workspaces ([{name, polygon, height}])")
    world = {k: v for k, v in base.items() if k in ("robot", "start", "params")}
    world["occupancyGrid"] = grid
    world["workspaces"] = [{"name": str(w["name"]), "height": float(w["height"]),
                            "polygon": [[float(x), float(y)] for x, y in w["polygon"]]}
                           for w in workspaces]
    if not all(math.isfinite(v) for w in world["workspaces"] for p in w["polygon"] for v in p):
        raise ValueError("~workspaces: a polygon point is not a finite number")
    return world

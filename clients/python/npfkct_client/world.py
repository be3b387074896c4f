"""A session's world: the prior map a robot tells the server (schemas/common.schema.json, World)."""

import json
from typing import Any, Dict, List, Optional

from npfkct_client.maps import occupancy_grid_from_map_files, read_pcd, workspace_heights

# The members of a scenario file that are the robot's prior map (the rest, such as the objects
# and the target, is what the simulated world holds and the robot must find).
WORLD_KEYS = ("robot", "room", "mapResolution", "occupancyGrid", "furniture", "workspaces",
              "baseRegions", "discretePoses", "start", "params")


class World(dict):
    """The `world` of a create request, as the JSON object it is (a dict: every API call and
    json.dumps take it as one)."""

    @classmethod
    def from_scenario(cls, path: str) -> "World":
        """The prior-map part of a scenario file (scenarios/*.json, npfkct-scenegen's output)."""
        with open(path, encoding="utf-8") as f:
            scenario = json.load(f)
        if not isinstance(scenario, dict):
            raise ValueError(f"{path}: a scenario is a JSON object")
        return cls({k: scenario[k] for k in WORLD_KEYS if k in scenario})

    def with_map_files(self, yaml_path: str) -> "World":
        """A copy whose room is the occupancy grid of ROS map_server files (a YAML and its PGM)
        instead of the room and the map resolution."""
        out = World(self)
        out.pop("room", None)
        out.pop("mapResolution", None)
        out["occupancyGrid"] = occupancy_grid_from_map_files(yaml_path)
        return out

    def with_workspaces(self, workspaces: List[Dict[str, Any]],
                        pcd_path: Optional[str] = None) -> "World":
        """A copy whose workspaces are these polygons ({name, polygon, height}) in place of its
        workspace furniture; a workspace given without a height gets the one measured in the
        point-cloud map at `pcd_path` (workspace_heights)."""
        if any("height" not in w for w in workspaces):
            if pcd_path is None:
                raise ValueError("a workspace without a height needs a point-cloud map (PCD)")
            workspaces = workspace_heights(workspaces, read_pcd(pcd_path))
        out = World(self)
        out["furniture"] = [f for f in self.get("furniture", []) if not f.get("workspace")]
        if not out["furniture"]:
            del out["furniture"]
        out["workspaces"] = [dict(w) for w in workspaces]
        return out

    def to_json(self) -> Dict[str, Any]:
        return dict(self)

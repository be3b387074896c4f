"""Typed client for the npfkct planning server (see schemas/openapi.yaml)."""

# The package's version (pyproject.toml reads it from here).
__version__ = "0.1.0"

from npfkct_client.client import (
    Action,
    ApiError,
    Box,
    Detection,
    Face,
    ImageBox,
    NpfkctClient,
    Observation,
    Plan,
    PlanFuture,
    PointCloud,
    RobotConfig,
    Session,
    Stats,
)
from npfkct_client.maps import (occupancy_grid_from_map_files, read_pcd, slam_world,
                                traced_workspaces, workspace_heights, write_map_files)
from npfkct_client.world import World

__all__ = [
    "__version__",
    "Action",
    "ApiError",
    "Box",
    "Detection",
    "Face",
    "ImageBox",
    "NpfkctClient",
    "Observation",
    "Plan",
    "PlanFuture",
    "PointCloud",
    "RobotConfig",
    "Session",
    "Stats",
    "World",
    "occupancy_grid_from_map_files",
    "read_pcd",
    "slam_world",
    "traced_workspaces",
    "workspace_heights",
    "write_map_files",
]

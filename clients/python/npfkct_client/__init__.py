"""Typed client for the npfkct planning server (see schemas/openapi.yaml)."""

from npfkct_client.client import (
    Action,
    ApiError,
    Box,
    Detection,
    Face,
    NpfkctClient,
    Observation,
    Plan,
    PointCloud,
    RobotConfig,
    Session,
)

__all__ = [
    "Action",
    "ApiError",
    "Box",
    "Detection",
    "Face",
    "NpfkctClient",
    "Observation",
    "Plan",
    "PointCloud",
    "RobotConfig",
    "Session",
]

"""The npfkct Python client (clients/python): importable as installed, or from npfkct's source
tree next to this package (clients/ros/npfkct_ros/src/npfkct_ros -> clients/python)."""

import os
import sys

__all__ = ["ApiError", "NpfkctClient", "World"]

try:
    from npfkct_client import ApiError, NpfkctClient, World
except ImportError:
    sys.path.insert(0, os.path.normpath(os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "..", "python")))
    from npfkct_client import ApiError, NpfkctClient, World

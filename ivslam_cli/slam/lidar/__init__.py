"""The feature-less LiDAR pipeline (the "Guaranteed SLAM – practical considerations" slides,
University of Manchester: P_EMPTY / P_OBSTACLE from every beam, the old/new inclusion test, a
grid structure). See :mod:`.pipeline`; one module per stage of the algorithm."""

from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.pipeline import run, summary

MODE = "lidar"

__all__ = ["MODE", "Params", "run", "summary"]

"""The landmark CSP pipeline (the "Guaranteed SLAM – practical considerations" slides,
University of Manchester: SLAM as a CSP over all poses and landmarks, contracted by
forward-backward sweeps). See :mod:`.pipeline`."""

from ivslam_cli.slam.landmarks.params import Params
from ivslam_cli.slam.landmarks.pipeline import run, summary

MODE = "landmarks"
MULTI_ROBOT = True  # runs a log of several robots (LogData.robots) as one problem

__all__ = ["MODE", "MULTI_ROBOT", "Params", "run", "summary"]

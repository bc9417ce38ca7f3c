"""The pairs pipeline (Mustafa, Codres & Stancu, "Mobile Robot Mapping using Interval
Methods", Eq. 1–6): pairwise landmark displacement subpavings, intersected over time, and the
landmark map they imply. See :mod:`.pipeline`."""

from ivslam_cli.slam.pairs.params import Params
from ivslam_cli.slam.pairs.pipeline import run, summary

MODE = "pairs"

__all__ = ["MODE", "Params", "run", "summary"]

"""A submap of scans mapped at their true poses, and scans to match against it: the fixture of
the matcher and loop-search tests; logs with phantom returns (people near the laser)."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from ivslam_cli.config import resolve_config
from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.report.core import relative_pose, truth_at
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.map_update import update_map
from ivslam_cli.slam.lidar.matcher import Matcher

MAPPED = 50  # scans 0..49 (2.5 m of travel) at their true poses make the submap (the anchor: scan 0)


@lru_cache(maxsize=1)
def true_submap():
    """``(log, params, matcher, tmap, rel)``: the rooms log (seed 3, 130 scans), default
    parameters, a matcher, the submap of scans ``0 … MAPPED − 1`` at their true poses and every
    scan's true pose in scan 0's frame."""
    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=3, steps=130))
    params = LidarParams.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    sc = log.scans
    true = truth_at(log.truth, sc.stamp)
    rel = relative_pose(np.repeat(true[:1], len(sc), axis=0), true)  # every scan in scan 0's frame
    boxes = np.zeros((len(sc), 6))
    boxes[:, 0::2] = rel - 1e-9
    boxes[:, 1::2] = rel + 1e-9
    tmap = TileMap(params.eps)
    update_map(tmap, sc, boxes, params.beams, order=np.arange(MAPPED))
    return log, params, Matcher(params, sc), tmap, rel


def inside(p, boxes) -> bool:
    """True if the pose ``p`` (3,) lies in one of ``boxes`` (n, 6)."""
    return bool(np.any((boxes[:, 0] <= p[0]) & (p[0] <= boxes[:, 1]) & (boxes[:, 2] <= p[1]) & (p[1] <= boxes[:, 3])
                       & (boxes[:, 4] <= p[2]) & (p[2] <= boxes[:, 5])))


def prior_around(p, lo, hi, th_lo, th_hi) -> np.ndarray:
    """The box (6,) from ``p − lo`` to ``p + hi`` in x, y and ``θ − th_lo`` to ``θ + th_hi``."""
    return np.array([p[0] - lo[0], p[0] + hi[0], p[1] - lo[1], p[1] + hi[1], p[2] - th_lo, p[2] + th_hi])


def phantoms(seed=2, first=20, last=26, every=40, factor=0.3, steps=40):
    """``(log, bad)``: a rooms log and its copy whose scans ``first … last − 1`` have every
    ``every``-th valid beam returning at ``factor`` of its range (a person close to the laser:
    at the default 40, about 17 beams of a scan break the static world)."""
    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=seed, steps=steps))
    sc = log.scans
    r = sc.ranges.copy()
    for k in range(first, last):
        idx = np.arange(sc.offsets[k], sc.offsets[k + 1])
        idx = idx[sc.valid[idx]][::every]
        r[idx] *= factor
    return log, replace(log, scans=replace(sc, ranges=r))

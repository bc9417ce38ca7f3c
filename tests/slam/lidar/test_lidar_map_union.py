"""P_EMPTY of a scan whose pose lies in a union of boxes (:mod:`ivslam_cli.slam.lidar.map_union`):
cells of every box's P_EMPTY (all of their intersection but a rounding-level few), none already
free in the map, and never a cell meeting a true wall when one box of the union holds the true
pose (the others are anywhere in its hull)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.bench_lidar_map import slices_around
from ivslam_cli.paving.tiles import EMPTY, TileMap
from ivslam_cli.slam.lidar.map_union import union_empty
from ivslam_cli.slam.lidar.matcher import hull as hull_of
from ivslam_cli.slam.lidar.map_update import LidarBounds, _scan, map_union_free, scan_sets, sensor_boxes, update_map
from tests.helpers.hyp import examples
from tests.helpers.lidar_world import make_scans, random_box, random_pose, random_world, segments_meet_cells

EPS = 0.05


def _world(seed: int, wxy: float, wth: float, m: int):
    """A scan from a true pose, and a union of ``m`` heading slices of a box around it: the
    truth's slice keeps an (x, y) box holding the truth, the others random sub-boxes of the hull."""
    rng = np.random.default_rng(seed)
    segs, room = random_world(rng)
    pose = random_pose(rng, segs, room)
    bounds = LidarBounds(0.03, 0.01, 0.5 * 2 * math.pi / 1024)
    scans, _, _ = make_scans(rng, segs, pose[None], (0.1, 0.0, 0.0), bounds.bearing, bounds.range_abs,
                             bounds.range_rel)
    box = random_box(rng, pose, wxy, wth)
    return segs, bounds, scans, box, slices_around(rng, box, pose, m)


def _cells(a: np.ndarray) -> set:
    return set(map(tuple, a.tolist()))


def _union_empty(tmap, scans, union, bounds):
    r, v, a0, inc = _scan(scans, 0)
    ix, iy = union_empty(tmap.keys, tmap.slots, tmap.cells, r, v, a0, inc, sensor_boxes(union, scans.mount),
                         bounds.range_abs, bounds.range_rel, bounds.bearing, EPS, bounds.fill_gaps, 0.0)
    return np.column_stack([ix, iy])


@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.3), st.floats(0.0, math.radians(6)), st.integers(1, 6),
       st.booleans())
@settings(max_examples=examples(ci=20), deadline=None)
def test_union_empty_is_the_boxes_intersection_and_sound(seed, wxy, wth, m, hull_first):
    segs, bounds, scans, box, union = _world(seed, wxy, wth, m)
    tmap = TileMap(EPS)
    if hull_first:  # as the pipeline calls it: after the hull's update
        update_map(tmap, scans, box[None], bounds)
    got = _union_empty(tmap, scans, union, bounds)
    cells = _cells(got)
    assert len(cells) == got.shape[0]
    per_box = [_cells(scan_sets(scans, 0, b, bounds, EPS)[0]) for b in union]
    expected = set.intersection(*per_box)
    assert cells <= expected
    assert not np.any(tmap.get(got[:, 0], got[:, 1]) & EMPTY)
    free_before = {c for c in expected if tmap.get(c[0], c[1]) & EMPTY}
    missed = expected - free_before - cells
    assert len(missed) <= max(2, 0.01 * len(expected)), (len(missed), len(expected))
    bad = segments_meet_cells(segs, got, EPS)
    assert not bad.any(), f"{bad.sum()} cells meet a wall, e.g. {got[bad][:3]}"


def test_a_sheared_set_proves_more_than_its_hull():
    """Heading slices whose (x, y) boxes move with the heading (as a turning robot's do): the
    union proves cells free that its hull does not, and marks them in the map."""
    segs, bounds, scans, box, _ = _world(3, 0.0, 0.0, 1)
    pose = 0.5 * (box[0::2] + box[1::2])
    m, dth, dxy = 6, math.radians(8), 0.3
    union = np.empty((m, 6))
    for i in range(m):
        f = i / (m - 1) - 0.5
        c = pose + np.array([f * dxy, -f * dxy, f * dth])
        union[i] = [c[0] - 0.01, c[0] + 0.01, c[1] - 0.01, c[1] + 0.01, c[2] - dth / (2 * m), c[2] + dth / (2 * m)]
    hull = hull_of(union)
    tmap = TileMap(EPS)
    update_map(tmap, scans, hull[None], bounds)
    before = tmap.counts()["empty"]
    added = map_union_free(tmap, scans, 0, union, bounds)
    hull_free = _cells(scan_sets(scans, 0, hull, bounds, EPS)[0])
    assert added > 0.1 * len(hull_free)
    assert tmap.counts()["empty"] == before + added
    assert map_union_free(tmap, scans, 0, union, bounds) == 0  # nothing left to add

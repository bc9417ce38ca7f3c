"""LiDAR map update (second seed): tiles, P_OBSTACLE outer, P_EMPTY inner, old/new, map update.

Scans come from the cone LiDAR of ``tests/helpers/lidar_world.py`` in random wall worlds: beam
``i`` returns the distance to the nearest wall point within its cone ``a_i + [-r_α, r_α]`` (the
seed's sensor model), plus a bounded error ``|e| <= 0.999 (abs + rel d)``, as float32. The hit
point is that nearest point. Pose boxes (up to ±0.2 m, ±3°) hold the true robot pose at a random
place.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from ivslam_cli.logs.model import Scans
from ivslam_cli.paving.tiles import EMPTY, OBST_NEW, OBST_OLD, OBSTACLE, TILE, TileMap
from ivslam_cli.paving.tiles import EMPTY_STATE
from ivslam_cli.slam.lidar.geometry import box_bearings, box_ranges, range_bounds, sensor_box
from ivslam_cli.slam.lidar.map_update import LidarBounds, inclusion_new, scan_sets, update_map
from tests.helpers.hyp import examples, seeds
from tests.helpers.lidar_world import (
    A0,
    BEAMS,
    INC,
    RANGE_MAX,
    RANGE_MIN,
    make_scans,
    random_box,
    random_pose,
    random_world,
    segments_meet_cells,
)


# ---------------------------------------------------------------- truth checks
def cells_of_point(p: np.ndarray, eps: float) -> list[tuple[int, int]]:
    """Every closed cell that may hold ``p`` (both neighbours when it is on/near a border)."""
    out = []
    ixs = {math.floor(p[0] / eps), math.floor(p[0] / eps - 1e-9), math.floor(p[0] / eps + 1e-9)}
    iys = {math.floor(p[1] / eps), math.floor(p[1] / eps - 1e-9), math.floor(p[1] / eps + 1e-9)}
    for i in ixs:
        for j in iys:
            if i * eps - 1e-12 <= p[0] <= (i + 1) * eps + 1e-12 and j * eps - 1e-12 <= p[1] <= (j + 1) * eps + 1e-12:
                out.append((i, j))
    return out


def assert_obstacle_outer(obst: np.ndarray, hits: np.ndarray, mask: np.ndarray, eps: float) -> None:
    marked = set(map(tuple, obst.tolist()))
    for p in hits[mask]:
        cands = cells_of_point(p, eps)
        assert any(c in marked for c in cands), f"hit point {p} outside P_OBSTACLE (cells {cands})"


# ---------------------------------------------------------------- geometry kernels
@pytest.mark.parametrize("seed", seeds(ci=40))
def test_box_ranges_and_bearings_enclose_points(seed):
    rng = np.random.default_rng(seed)
    c = rng.uniform(-3, 3, 2)
    w = rng.uniform(0, 2, 2) * rng.choice([0.0, 1e-9, 0.1, 1.0], 2)
    xl, xh, yl, yh = c[0] - w[0], c[0] + w[0], c[1] - w[1], c[1] + w[1]
    lo, hi = box_ranges(xl, xh, yl, yh)
    bl, bh, full = box_bearings(xl, xh, yl, yh)
    pts = np.column_stack([rng.uniform(xl, xh, 500), rng.uniform(yl, yh, 500)])
    pts = np.vstack([pts, [[xl, yl], [xl, yh], [xh, yl], [xh, yh]]])
    r = np.hypot(pts[:, 0], pts[:, 1])
    assert np.all((lo <= r) & (r <= hi))
    assert full == (xl <= 0 <= xh and yl <= 0 <= yh)
    if not full:
        assert bh - bl < math.pi + 1e-9  # a box that misses the origin spans less than pi
        ang = np.arctan2(pts[:, 1], pts[:, 0])
        k = np.ceil((bl - ang) / (2 * math.pi))  # the copy of each angle at or above bl
        ang = ang + 2 * math.pi * k
        assert np.all((bl <= ang) & (ang <= bh)), (bl, bh)


@pytest.mark.parametrize("seed", seeds(ci=30))
def test_sensor_box_encloses_mounted_poses(seed):
    rng = np.random.default_rng(seed)
    pose = np.array([*rng.uniform(-50, 50, 2), rng.uniform(-10, 10)])
    box = random_box(rng, pose, 0.2, 0.05)
    mount = (*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
    sb = sensor_box(*box, *mount)
    for _ in range(200):
        x, y, th = (rng.uniform(box[0], box[1]), rng.uniform(box[2], box[3]), rng.uniform(box[4], box[5]))
        s = (x + math.cos(th) * mount[0] - math.sin(th) * mount[1],
             y + math.sin(th) * mount[0] + math.cos(th) * mount[1], th + mount[2])
        assert sb[0] <= s[0] <= sb[1] and sb[2] <= s[1] <= sb[3] and sb[4] <= s[2] <= sb[5]


# ---------------------------------------------------------------- tiles
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.05, 0.1, 0.013]))
@settings(max_examples=examples(ci=20))
def test_tiles_store_union_intersection_dense(seed, eps):
    rng = np.random.default_rng(seed)
    spread = int(rng.choice([50, 300, 1500]))
    n = int(rng.integers(1, 3000))
    a_ix, a_iy = rng.integers(-spread, spread, n), rng.integers(-spread, spread, n)
    a_f = rng.integers(1, 8, n).astype(np.uint8)
    b_ix, b_iy = a_ix + rng.integers(-3, 4, n), a_iy + rng.integers(-3, 4, n)
    b_f = rng.integers(1, 8, n).astype(np.uint8)
    A, B = TileMap(eps, capacity=1), TileMap(eps)
    A.set(a_ix, a_iy, a_f)
    B.set(b_ix, b_iy, b_f)
    ref_a, ref_b = {}, {}
    for ref, ix, iy, f in ((ref_a, a_ix, a_iy, a_f), (ref_b, b_ix, b_iy, b_f)):
        for i, j, v in zip(ix.tolist(), iy.tolist(), f.tolist()):
            ref[(i, j)] = ref.get((i, j), 0) | v
    keys = list(ref_a)
    assert np.array_equal(A.get(*np.array(keys).T), np.array([ref_a[k] for k in keys], np.uint8))
    assert np.all(A.get(a_ix + 10 * spread + 10 * TILE, a_iy) == 0)  # never written
    tiles_a = {(i >> 6, j >> 6) for i, j in ref_a}
    assert A.n_tiles == len(tiles_a)
    U, I = A.union(B), A.intersection(B)
    probe = np.array(sorted(set(ref_a) | set(ref_b)))
    exp_u = np.array([ref_a.get(k, 0) | ref_b.get(k, 0) for k in map(tuple, probe.tolist())], np.uint8)
    exp_i = np.array([ref_a.get(k, 0) & ref_b.get(k, 0) for k in map(tuple, probe.tolist())], np.uint8)
    assert np.array_equal(U.get(*probe.T), exp_u)
    assert np.array_equal(I.get(*probe.T), exp_i)
    if spread > 300:
        return  # the dense export of a 3000-cell-wide box is tested at smaller spreads
    # dense export: every cell in place, states derived from flags
    D = U.dense(raw=True)
    assert np.array_equal(D.data[probe[:, 0] - D.i0, probe[:, 1] - D.j0], exp_u)
    assert D.data.sum(dtype=np.int64) == exp_u.sum(dtype=np.int64)
    S = U.dense()
    st_exp = np.where(exp_u & EMPTY, EMPTY_STATE, np.where(((exp_u & OBST_NEW) > 0) & ((exp_u & OBST_OLD) > 0), OBSTACLE, 0))
    assert np.array_equal(S.data[probe[:, 0] - D.i0, probe[:, 1] - D.j0], st_exp)
    counts = U.counts()
    assert counts["empty"] == int((st_exp == EMPTY_STATE).sum())
    assert counts["obstacle"] == int((st_exp == OBSTACLE).sum())
    assert counts["unknown"] + counts["empty"] + counts["obstacle"] == U.n_tiles * TILE * TILE
    k_empty = counts["empty"]
    assert U.area("empty", upward=False) <= k_empty * eps * eps <= U.area("empty", upward=True)


def test_tiles_reject_other_resolutions():
    with pytest.raises(ValueError):
        TileMap(0.05).union(TileMap(0.1))
    with pytest.raises(ValueError):
        TileMap(0.0)


def test_tile_index_int32_coordinates():
    """A tile beyond the index's int32 coordinates is never found (unknown: nothing proven) and
    cannot be allocated; its key does not wrap onto an allocated tile."""
    from ivslam_cli.paving.tiles import add_tile, find

    m = TileMap(0.05)
    keys, slots, cells, coords, n = m.arrays()
    i, keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n, 0, 0)
    assert find(keys, slots, 0, 0) == i
    for tx, ty in ((2**32, 0), (0, 2**32), (-(2**31) - 1, 0), (0, 2**31)):
        assert find(keys, slots, tx, ty) == -1  # (2^32, 0) packs like (0, 0) without the check
        with pytest.raises(ValueError):
            add_tile(keys, slots, cells, coords, n, tx, ty)
    assert find(keys, slots, 2**31 - 1, -(2**31)) == -1


# ---------------------------------------------------------------- P_OBSTACLE, P_EMPTY
def _case(seed: int, wxy: float, wth: float, alpha_factor: float, eps: float, full=False):
    rng = np.random.default_rng(seed)
    segs, room = random_world(rng)
    pose = random_pose(rng, segs, room)
    mount = (float(rng.uniform(-0.15, 0.15)), float(rng.uniform(-0.05, 0.05)), float(rng.choice([0.0, math.pi / 2, math.pi])))
    half = alpha_factor * INC
    bounds = LidarBounds(0.03, 0.01, half)
    scans, hits, mask = make_scans(rng, segs, pose[None], mount, half, bounds.range_abs, bounds.range_rel,
                                   noise=str(rng.choice(["uniform", "edges"])))
    box = random_box(rng, pose, wxy, wth, full)
    return segs, pose, box, bounds, scans, hits[0], mask[0]


@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.2), st.floats(0.0, math.radians(3)),
       st.sampled_from([0.5, 0.75, 2.0]), st.sampled_from([0.05, 0.1]))
@settings(max_examples=examples(ci=25))
def test_scan_sets_sound_against_truth(seed, wxy, wth, alpha_factor, eps):
    """Every true hit point is in P_OBSTACLE^k; no P_EMPTY^k cell meets a wall."""
    segs, pose, box, bounds, scans, hits, mask = _case(seed, wxy, wth, alpha_factor, eps)
    assert mask.sum() > 100
    empty, obst = scan_sets(scans, 0, box, bounds, eps)
    assert_obstacle_outer(obst, hits, mask, eps)
    bad = segments_meet_cells(segs, empty, eps)
    assert not bad.any(), f"{bad.sum()} P_EMPTY cells meet a wall, e.g. {empty[bad][:3]}"
    assert len(set(map(tuple, empty.tolist()))) == empty.shape[0]  # blocks do not overlap
    # the hull-only leaf test is outer too, and never tighter than the beam-by-beam one
    _, obst_hull = scan_sets(scans, 0, box, bounds, eps, exact=False)
    assert set(map(tuple, obst.tolist())) <= set(map(tuple, obst_hull.tolist()))


def test_no_return_beams_prove_nothing():
    segs, pose, box, bounds, scans, hits, mask = _case(5, 0.1, 0.02, 0.5, 0.05)
    scans.valid[:] = False
    empty, obst = scan_sets(scans, 0, box, bounds, 0.05)
    assert empty.shape[0] == 0 and obst.shape[0] == 0


@pytest.mark.parametrize("smin", [0.3, 1.0, 2.5])
def test_near_cells_not_empty_below_smin(smin):
    """``smin``: P_EMPTY^k loses exactly the cells nearer than it to the sensor box (the beams of
    a sweep, taken from poses apart, leave slivers there: free_cones.sweep_free_from)."""
    eps = 0.05
    segs, pose, box, bounds, scans, hits, mask = _case(7, 0.05, 0.01, 0.75, eps)
    full = set(map(tuple, scan_sets(scans, 0, box, bounds, eps)[0].tolist()))
    cut = set(map(tuple, scan_sets(scans, 0, box, bounds, eps, smin=smin)[0].tolist()))
    assert cut <= full and len(cut) > 0
    sb = sensor_box(*box, *scans.mount)
    for ix, iy in full:
        r_lo = box_ranges(ix * eps - sb[1], (ix + 1) * eps - sb[0], iy * eps - sb[3], (iy + 1) * eps - sb[2])[0]
        if (ix, iy) in cut:
            assert r_lo >= smin - 1e-9
        else:
            assert r_lo < smin + 1e-9
    assert not scan_sets(scans, 0, box, bounds, eps, smin=math.inf)[0].size


# a seed only, but not explicit seeds: assume() (below) makes Hypothesis draw until 12 worlds
# have an oracle requiring >= 50 cells
@given(st.integers(0, 2**32 - 1))
@settings(max_examples=examples(ci=12), suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
def test_empty_is_nontrivial_with_uncertain_heading(seed):
    """With ±3° (17 beams) of heading no single beam cone holds a cell's bearings, yet the scan as
    a whole proves every cell that a generous independent bound says is clearly free: seen from
    the true sensor pose, every beam within (heading width + the cell's angular spread over the
    box) of its bearing returns farther than the cell's distance + (box diameter + cell)."""
    eps = 0.05
    segs, pose, box, bounds, scans, hits, mask = _case(seed, 0.2, math.radians(3), 0.5, eps, full=True)
    assert box[5] - box[4] > 10 * 2 * max(bounds.bearing, INC / 2)  # beam by beam: nothing provable
    empty, _ = scan_sets(scans, 0, box, bounds, eps)
    proven = set(map(tuple, empty.tolist()))
    sb = sensor_box(*box, *scans.mount)
    mx, my, myaw = scans.mount
    c = np.array([pose[0] + math.cos(pose[2]) * mx - math.sin(pose[2]) * my,
                  pose[1] + math.sin(pose[2]) * mx + math.cos(pose[2]) * my])
    yaw = pose[2] + myaw
    free = np.where(scans.valid, (scans.ranges.astype(np.float64) - 0.03) / 1.01, -np.inf)
    diam = math.hypot(sb[1] - sb[0], sb[3] - sb[2])
    R = RANGE_MAX
    ix = np.arange(math.floor((c[0] - R) / eps), math.floor((c[0] + R) / eps) + 1)
    iy = np.arange(math.floor((c[1] - R) / eps), math.floor((c[1] + R) / eps) + 1)
    gx, gy = np.meshgrid(ix, iy, indexing="ij")
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    v = (cells + 0.5) * eps - c
    dist = np.hypot(v[:, 0], v[:, 1])
    keep = dist > diam + 2 * eps
    cells, dist, v = cells[keep], dist[keep], v[keep]
    ang = (np.arctan2(v[:, 1], v[:, 0]) - yaw + math.pi) % (2 * math.pi) - math.pi
    margin = (sb[5] - sb[4]) + np.arcsin(np.minimum(1.0, (diam + eps) / dist)) + 2 * INC + 1e-3
    j0 = np.floor((ang - margin - A0) / INC).astype(np.int64)
    j1 = np.ceil((ang + margin - A0) / INC).astype(np.int64)
    inside = (j0 >= 0) & (j1 <= BEAMS - 1)
    cells, dist, j0, j1 = cells[inside], dist[inside], j0[inside], j1[inside]
    lvl = [free]  # sparse table of minima (numpy): the oracle's own, independent of the kernel's
    while 2 ** len(lvl) <= BEAMS:
        prev, half = lvl[-1], 2 ** (len(lvl) - 1)
        lvl.append(np.minimum(prev[:-half], prev[half:]))
    k = np.floor(np.log2(j1 - j0 + 1)).astype(np.int64)
    wmin = np.array([min(lvl[kk][a], lvl[kk][b - 2**kk + 1]) for kk, a, b in zip(k, j0, j1)])
    required = cells[dist + eps + diam + 0.02 < wmin]
    missing = [tuple(p) for p in required.tolist() if tuple(p) not in proven]
    assert not missing, f"{len(missing)} of {required.shape[0]} clearly free cells not proven"
    assume(required.shape[0] >= 50)  # count only the worlds where the oracle requires something


# ---------------------------------------------------------------- map update and old/new
def _walk(seed: int, n: int, step: float, wxy: float = 0.2, wth: float = math.radians(3),
          length: float = 30.0):
    """Scans every ``step`` m along a 3 m wide corridor of ``length`` m with a few obstacles."""
    rng = np.random.default_rng(seed)
    L = length
    segs = np.array([[0, 0, L, 0], [L, 0, L, 3], [L, 3, 0, 3], [0, 3, 0, 0],
                     [5, 0, 5, 0.8], [12, 3, 12, 2.0], [20, 1.3, 20.6, 1.3]], dtype=np.float64)
    segs = segs[np.maximum(segs[:, 0], segs[:, 2]) <= L]
    poses = np.column_stack([1.5 + step * np.arange(n), np.full(n, 1.5) + rng.uniform(-0.2, 0.2, n),
                             rng.uniform(-0.3, 0.3, n)])
    bounds = LidarBounds(0.03, 0.01, INC)
    scans, hits, mask = make_scans(rng, segs, poses, (0.1, 0.0, 0.0), bounds.bearing, 0.03, 0.01)
    boxes = np.array([random_box(rng, p, wxy, wth) for p in poses])
    return segs, poses, boxes, bounds, scans, hits, mask


def test_tiles_grow_with_explored_area():
    segs, poses, boxes, bounds, scans, hits, mask = _walk(1, 12, 2.0)
    m = TileMap(0.05)
    tiles, nbytes = [], []
    for k in range(len(scans)):
        update_map(m, scans, boxes, bounds, order=[k])
        tiles.append(m.n_tiles)
        nbytes.append(m.nbytes)
    assert all(b >= a for a, b in zip(tiles, tiles[1:]))
    assert tiles[-1] >= 3 * tiles[0]  # 22 m of corridor vs one 5.6 m scan
    assert nbytes[-1] > nbytes[0]
    co = m.tile_coords() * TILE * 0.05
    # from the start (the wall behind it is outside the 240° field of view) to 5.6 m past the
    # last pose, and below y = 0 (the outer band of the wall y = 0 reaches past it)
    assert co[:, 0].min() <= poses[0, 0] and co[:, 0].max() + TILE * 0.05 >= poses[-1, 0] + 3.0
    assert co[:, 1].min() < 0
    # the tiles are those written: a map of the first scan alone has as many as step 0
    m0 = TileMap(0.05)
    update_map(m0, scans, boxes, bounds, order=[0])
    assert m0.n_tiles == tiles[0]


@pytest.mark.parametrize("seed", seeds(ci=6))
def test_map_update_sound_and_old_new(seed):
    """Scans along a corridor, twice: first pass beams over new ground are new, a second pass
    over the same scans finds every valid beam old; P_EMPTY never meets a wall; every hit
    point seen by a new and an old beam is a P_OBSTACLE cell."""
    eps = 0.05
    segs, poses, boxes, bounds, scans, hits, mask = _walk(seed, 6, 0.7)
    m = TileMap(eps)
    first = update_map(m, scans, boxes, bounds)
    b0, b1 = scans.offsets[0], scans.offsets[1]
    assert not first.is_old[b0:b1].any()  # the very first scan: an empty map, all new
    assert first.stats[0, 3] == scans.valid[b0:b1].sum()
    second = update_map(m, scans, boxes, bounds)
    assert np.array_equal(second.is_old, scans.valid)  # everything was measured by pass one
    assert np.all(second.stats[:, 3] == 0)
    d = m.dense()
    free = np.argwhere(d.data == EMPTY_STATE) + [d.i0, d.j0]
    assert free.shape[0] > 1000
    assert not segments_meet_cells(segs, free, eps).any()
    obst = np.argwhere(d.data == OBSTACLE) + [d.i0, d.j0]
    for k in range(len(scans)):
        assert_obstacle_outer(obst, hits[k], mask[k], eps)


def test_old_new_full_and_cheap_forms():
    """Both forms on an 8 m corridor (every beam returns): all new on an empty map; after five
    scans 0.5 m apart, most beams of the next scan are old in both forms, not all."""
    eps = 0.05
    segs, poses, boxes, bounds, scans, hits, mask = _walk(3, 7, 0.5, length=8.0)
    m = TileMap(eps)
    valid0 = scans.valid[:BEAMS]
    assert np.array_equal(inclusion_new(m, scans, 0, boxes[0], bounds), valid0)
    assert not update_map(m, scans, boxes, bounds, order=[0], write=False).is_old.any()
    assert m.n_tiles == 0  # write=False leaves the map untouched
    update_map(m, scans, boxes, bounds, order=[0, 1, 2, 3, 4])
    before = m.cells[: m.n].copy()
    k = 5
    sl = slice(k * BEAMS, (k + 1) * BEAMS)
    v = scans.valid[sl]
    cheap_old = update_map(m, scans, boxes, bounds, order=[k], write=False).is_old[sl]
    assert np.array_equal(m.cells[: m.n], before)
    full_new = inclusion_new(m, scans, k, boxes[k], bounds)
    assert not cheap_old[~v].any() and not full_new[~v].any()
    full_old = v & ~full_new
    assert 0.6 * v.sum() < cheap_old.sum() < v.sum()
    assert 0.6 * v.sum() < full_old.sum() < v.sum()
    # the cheap form is exact for what it tests: a beam is new iff a cell of its
    # P_OBSTACLE^{i,k} was unmeasured; beams far from the explored end are old in both
    _, obst = scan_sets(scans, k, boxes[k], bounds, eps)
    assert (m.get(obst[:, 0], obst[:, 1]) == 0).any() == bool((v & ~cheap_old).any())


# ---------------------------------------------------------------- fast path vs the reference
# lidar_kernel keeps the cell-by-cell quadtree as *_reference: the fast path (certified blocks,
# fast bearings with an error filter, O(1) window tests) must give the same cells, beams, map
# flags, tile order and counts, bit for bit.
from ivslam_cli.slam.lidar import map_kernel as K  # noqa: E402
from ivslam_cli.slam.lidar.geometry import ATAN_ERR, atan2_fast, atan_poly  # noqa: E402
from ivslam_cli.slam.lidar.map_update import sensor_boxes  # noqa: E402

GEOMETRIES = {  # name: (beams, angle_min, increment)
    "urg": (BEAMS, A0, INC),
    "360": (360, -math.pi, 2 * math.pi / 360),
    "full-overlap": (400, -math.pi, 2 * math.pi / 380),  # more than one turn
    "narrow": (181, -0.5 * math.pi, math.pi / 180),
}


def ray_scans(rng, segs, poses, mount, geometry, r_abs, r_rel, invalid=0.0, phantom=0.0):
    """Nominal-ray scans of ``segs`` from robot poses (T, 3) for a scan ``geometry``: bounded
    noise, some beams made invalid, some phantom returns (short ranges); no truth needed."""
    nb, a0, inc = GEOMETRIES[geometry]
    T = poses.shape[0]
    a, d = segs[:, :2], segs[:, 2:] - segs[:, :2]
    out_r, out_v = [], []
    for k in range(T):
        x, y, th = poses[k]
        o = np.array([x + math.cos(th) * mount[0] - math.sin(th) * mount[1],
                      y + math.sin(th) * mount[0] + math.cos(th) * mount[1]])
        beta = th + mount[2] + a0 + inc * np.arange(nb)
        u = np.stack([np.cos(beta), np.sin(beta)], 1)[:, None, :]  # (B, 1, 2)
        w = a[None] - o  # (1, K, 2)
        den = u[..., 0] * d[None, :, 1] - u[..., 1] * d[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * d[None, :, 1] - w[..., 1] * d[None, :, 0]) / den
            s = (w[..., 0] * u[..., 1] - w[..., 1] * u[..., 0]) / den
        t = np.where((den != 0) & (s >= 0) & (s <= 1) & (t > 0), t, np.inf).min(1)
        t = np.where(rng.random(nb) < phantom, rng.uniform(0.1, 1.0, nb) * np.minimum(t, RANGE_MAX), t)
        b = r_abs + r_rel * np.where(np.isfinite(t), t, 0.0)
        z = np.where(np.isfinite(t), t + 0.999 * rng.uniform(-1, 1, nb) * b, 0.0).astype(np.float32)
        ok = np.isfinite(t) & (z >= np.float32(RANGE_MIN)) & (z <= np.float32(RANGE_MAX))
        ok &= rng.random(nb) >= invalid
        out_r.append(np.where(ok, z, np.float32(0.0)))
        out_v.append(ok)
    ones = np.ones(T)
    return Scans(stamp=np.arange(T) * 0.1, angle_min=ones * a0, angle_increment=ones * inc,
                 range_min=ones * RANGE_MIN, range_max=ones * RANGE_MAX,
                 offsets=np.arange(T + 1, dtype=np.int64) * nb,
                 ranges=np.concatenate(out_r), valid=np.concatenate(out_v), mount=tuple(mount))


def _cellset(ix, iy):
    cells = list(zip(ix.tolist(), iy.tolist()))
    assert len(set(cells)) == len(cells)  # blocks and cells never overlap
    return set(cells)


def _random_scan_case(seed):
    rng = np.random.default_rng(seed)
    segs, room = random_world(rng)
    pose = random_pose(rng, segs, room)
    pose[2] = rng.uniform(-8.0, 8.0)  # headings beyond +-pi: every branch of the windows
    geometry = str(rng.choice(list(GEOMETRIES)))
    mount = (float(rng.uniform(-0.15, 0.15)), float(rng.uniform(-0.05, 0.05)),
             float(rng.choice([0.0, math.pi / 2, math.pi, rng.uniform(-4, 4)])))
    inc = GEOMETRIES[geometry][2]
    bounds = LidarBounds(0.03, 0.01, float(rng.choice([0.0, 0.5, 0.75, 2.0])) * inc)
    scans = ray_scans(rng, segs, pose[None], mount, geometry, 0.03, 0.01,
                      invalid=float(rng.choice([0.0, 0.1, 0.6])), phantom=float(rng.choice([0.0, 0.05])))
    wxy = float(rng.choice([0.0, 0.02, 0.2, 0.3]))
    wth = float(rng.choice([0.0, math.radians(0.5), math.radians(3), math.radians(5)]))
    box = random_box(rng, pose, wxy, wth, full=bool(rng.random() < 0.5))
    eps = float(rng.choice([0.05, 0.1, 0.031]))
    return scans, box, bounds, eps


@pytest.mark.parametrize("seed", seeds(ci=60))
def test_fast_scan_cells_equal_reference(seed):
    """P_EMPTY^k and P_OBSTACLE^k (beam-by-beam and hull modes) of the fast path are the
    reference's, over scan geometries (240°, 360°, more than a turn, 180°), headings in
    [-8, 8] rad, rotated mounts, pose boxes from a point to ±0.3 m / ±5°, ray-like and wide
    beams, invalid beams and phantom returns."""
    scans, box, bounds, eps = _random_scan_case(seed)
    sb = sensor_boxes(box, scans.mount)[0]
    args = (scans.ranges, scans.valid, float(scans.angle_min[0]), float(scans.angle_increment[0]), sb,
            bounds.range_abs, bounds.range_rel, bounds.bearing, eps)
    for exact in (True, False):
        new = K.scan_cells(*args, exact)
        ref = K.scan_cells_reference(*args, exact)
        assert _cellset(new[0], new[1]) == _cellset(ref[0], ref[1])
        assert _cellset(new[2], new[3]) == _cellset(ref[2], ref[3])
        # P_EMPTY^k alone (the map union's first box): the same cells, no obstacle traversal
        only = K.scan_cells(*args, exact, True, 0.0, False)
        assert _cellset(only[0], only[1]) == _cellset(ref[0], ref[1]) and only[2].size == 0


def _run_log(fn, tmap, scans, boxes, bounds, order, exact, write, smin=None):
    is_old = np.zeros(scans.ranges.shape[0], dtype=np.bool_)
    stats = np.zeros((len(scans), 6), dtype=np.int64)
    smin = np.zeros(len(scans)) if smin is None else np.asarray(smin, float)
    arrays = fn(*tmap.arrays(), scans.ranges, scans.valid, scans.offsets, scans.angle_min, scans.angle_increment,
                sensor_boxes(boxes, scans.mount), np.asarray(order, np.int64), bounds.range_abs,
                bounds.range_rel, bounds.bearing, tmap.eps, exact, write, is_old, stats, True, smin)
    tmap.set_arrays(*arrays)
    return is_old, stats


def _same_maps(a: TileMap, b: TileMap) -> None:
    assert a.n == b.n
    assert np.array_equal(a.coords[: a.n], b.coords[: b.n])  # same tiles, allocated in the same order
    assert np.array_equal(a.cells[: a.n], b.cells[: b.n])


@pytest.mark.parametrize("seed", seeds(ci=8))
def test_fast_update_log_equal_reference(seed):
    """The map update over a log (new ground, then the same ground again, in another order and
    without writing) gives the reference's map (flags, tiles and their order), old/new beams
    and counts of empty cells, obstacle cells, new and old beams."""
    rng = np.random.default_rng(seed)
    segs, room = random_world(rng)
    poses = np.array([random_pose(rng, segs, room) for _ in range(6)])
    poses[:, 2] += rng.choice([0.0, 2 * math.pi, -4 * math.pi])
    geometry = str(rng.choice(["urg", "360"]))
    mount = (0.1, 0.0, float(rng.choice([0.0, math.pi])))
    inc = GEOMETRIES[geometry][2]
    bounds = LidarBounds(0.03, 0.01, float(rng.choice([0.0, 1.0])) * inc)
    invalid = float(rng.choice([0.0, 0.1]))
    scans = ray_scans(rng, segs, poses, mount, geometry, 0.03, 0.01, invalid=invalid, phantom=0.02)
    boxes = np.array([random_box(rng, p, 0.2, math.radians(3)) for p in poses])
    eps = float(rng.choice([0.05, 0.1]))
    for exact in (True, False):
        new, ref = TileMap(eps), TileMap(eps)
        runs = [(np.arange(len(scans)), True), (rng.permutation(len(scans)), True),
                (rng.permutation(len(scans))[:3], False)]
        # no cell nearer than smin to the sensor box proven empty (a sweep's beams apart)
        smin = rng.choice([0.0, 0.0, 0.4, 1.5, np.inf], size=len(scans))
        for order, write in runs:
            a = _run_log(K.update_log, new, scans, boxes, bounds, order, exact, write, smin)
            b = _run_log(K.update_log_reference, ref, scans, boxes, bounds, order, exact, write, smin)
            _same_maps(new, ref)
            assert np.array_equal(a[0], b[0])  # old beams
            assert np.array_equal(a[1][:, 1:5], b[1][:, 1:5])  # empty, obstacle, new, old counts
        assert new.counts()["obstacle"] > 0
        assert new.counts()["empty"] > 0 or invalid > 0  # invalid beams prove no free space


def test_fast_path_grows_its_buffers():
    """Buffers too small for a scan are reported (and the scan redone with larger ones): on a
    fine grid, with thousands of records, the same cells as the reference."""
    rng = np.random.default_rng(11)
    segs, room = random_world(rng)
    pose = random_pose(rng, segs, room)
    scans = ray_scans(rng, segs, pose[None], (0.0, 0.0, 0.0), "urg", 0.03, 0.01)
    bounds = LidarBounds(0.03, 0.01, 0.0)
    sb = sensor_boxes(random_box(rng, pose, 0.05, math.radians(0.5)), scans.mount)[0]
    args = (scans.ranges, scans.valid, float(scans.angle_min[0]), float(scans.angle_increment[0]), sb,
            bounds.range_abs, bounds.range_rel, bounds.bearing, 0.011)
    nb = BEAMS
    lg, T = K._fast_buffers(nb)
    small = [np.empty((1, 3), np.int64), np.empty((1, 4), np.int64), np.empty((1, 6), np.int64),
             np.empty((1, 6), np.int64), np.empty((1, 2))]
    keys, slots, cells = np.full(4, np.iinfo(np.int64).min), np.full(4, -1), np.zeros((1, TILE, TILE), np.uint8)
    ok = K.traverse(keys, slots, cells, *args[:9], True, lg, T, np.zeros(nb, np.bool_), *small,
                    np.zeros(4, np.int64), *K._level_buffers())[0]
    assert not ok
    # work arrays too small for the blocks of a level: their size is asked for
    wf, wi = np.empty((K._WF, 4)), np.empty((K._WI, 4), np.int64)
    r = K.traverse(keys, slots, cells, *args[:9], True, lg, T, np.zeros(nb, np.bool_), *K._record_buffers(),
                   np.zeros(4, np.int64), wf, wi)
    assert not r[0] and r[5] > 4
    r = K._traverse_grown(keys, slots, cells, *args[:9], True, lg, T, np.zeros(nb, np.bool_),
                          *K._record_buffers(), np.zeros(4, np.int64), wf, wi, True, 0.0)
    assert r[10].shape[1] > 4
    tx0, tx1, ty0, ty1 = K._tile_range(*sb[:4], float(T[0, :nb, 1].max()), 0.011)
    assert (tx1 - tx0 + 1) * (ty1 - ty0 + 1) > 2 * K._CHUNK  # several chunks of tiles
    new, ref = K.scan_cells(*args, True), K.scan_cells_reference(*args, True)
    assert new[2].shape[0] > 4096 and new[0].shape[0] > 1024
    assert _cellset(new[0], new[1]) == _cellset(ref[0], ref[1])
    assert _cellset(new[2], new[3]) == _cellset(ref[2], ref[3])


def test_atan2_fast_error_bound():
    """ATAN_ERR bounds |atan2_fast - atan2|: the polynomial's error at 2^22 + 1 points of [0, 1]
    plus its largest possible change between two of them (|d/dt (P - atan)| <= sum |(2k+1) c_k|
    + 1), then the argument reduction on random and special inputs."""
    from numba import njit

    @njit
    def poly(t):
        out = np.empty(t.shape[0])
        for i in range(t.shape[0]):
            out[i] = atan_poly(t[i])
        return out

    @njit
    def fast(y, x):
        out = np.empty(y.shape[0])
        for i in range(y.shape[0]):
            out[i] = atan2_fast(y[i], x[i])
        return out

    from ivslam_cli.slam.lidar import geometry as G

    n = 2**22
    t = np.linspace(0.0, 1.0, n + 1)
    sampled = float(np.max(np.abs(poly(t) - np.arctan(t))))
    lip = sum(abs((2 * k + 1) * c) for k, c in enumerate(G.ATAN_COEFFS)) + 1.0
    assert sampled + lip * 0.5 / n + 1e-15 < ATAN_ERR / 2  # half of the bound for the reduction
    rng = np.random.default_rng(1)
    ang = np.concatenate([rng.uniform(-math.pi, math.pi, 200_000), np.arange(-8, 9) * math.pi / 8])
    r = 10.0 ** rng.uniform(-8, 6, ang.shape[0])
    y, x = r * np.sin(ang), r * np.cos(ang)
    err = np.abs(fast(y, x) - np.arctan2(y, x))
    err = np.minimum(err, 2 * math.pi - err)  # +-pi
    assert err.max() < ATAN_ERR
    assert fast(np.zeros(1), np.zeros(1))[0] == 0.0


@pytest.mark.parametrize("seed", seeds(ci=40))
def test_window_meets_test_is_exact(seed):
    """The scan's table gives a window's hull, and ``_meets`` (hull, then the largest gap
    between consecutive valid beams, then a scan) answers "does a valid beam of [l, r] have
    lo <= a and hi >= b" exactly."""
    rng = np.random.default_rng(seed)
    nb = int(rng.integers(1, 300))
    z = np.cumsum(rng.normal(0, rng.choice([0.01, 0.1, 1.0]), nb)) + 3.0
    z = np.where(rng.random(nb) < 0.05, rng.uniform(0.1, 6.0, nb), np.abs(z) + 0.05)  # jumps
    valid = rng.random(nb) >= rng.choice([0.0, 0.3, 0.9])
    lg, T = K._fast_buffers(nb)
    K._fast_tables(z.astype(np.float32), valid, 0.03, 0.01, 1.0, T)
    st_ = np.zeros(4, dtype=np.int64)
    lo, hi = T[0, :, 0], T[0, :, 1]
    for _ in range(300):
        l = int(rng.integers(0, nb))
        r = int(rng.integers(l, min(nb, l + int(rng.choice([1, 5, 50, 300])))))
        c = rng.uniform(0.0, 7.0)
        w = rng.choice([0.0, 0.05, 0.3, 1.0])
        a, b = c + w, c
        expect = bool(np.any(valid[l : r + 1] & (lo[l : r + 1] <= a) & (hi[l : r + 1] >= b)))
        lo_min, hi_max, _, _ = K._win(T, lg, l, r)
        assert lo_min == lo[l : r + 1].min() and hi_max == hi[l : r + 1].max()
        assert K._meets(T, lg, l, r, a, b, lo_min, hi_max, st_) == expect


def test_update_map_scan_by_scan_equals_one_call():
    """Scans given one call each (as a pipeline contracting poses does) or all at once: the same
    map, old beams and counts; only the boxes of the scans processed are converted, every box is
    still checked."""
    segs, poses, boxes, bounds, scans, hits, mask = _walk(4, 5, 0.8)
    a, b = TileMap(0.05), TileMap(0.05)
    one = update_map(a, scans, boxes, bounds)
    is_old = np.zeros_like(one.is_old)
    stats = np.zeros_like(one.stats)
    for k in range(len(scans)):
        r = update_map(b, scans, boxes, bounds, order=[k])
        sl = slice(scans.offsets[k], scans.offsets[k + 1])
        is_old[sl] = r.is_old[sl]
        stats[k] = r.stats[k]
        assert not r.is_old[scans.offsets[k + 1]:].any() and not r.stats[k + 1:].any()
    _same_maps(a, b)
    assert np.array_equal(one.is_old, is_old) and np.array_equal(one.stats[:, 1:5], stats[:, 1:5])
    with pytest.raises(ValueError):
        update_map(b, scans, boxes, bounds, order=[len(scans)])
    with pytest.raises(ValueError):
        update_map(b, scans, boxes, bounds, order=[-1])
    bad = boxes.copy()
    bad[-1, 0] = np.nan  # a scan not processed: its box is still checked
    with pytest.raises(ValueError):
        update_map(b, scans, bad, bounds, order=[0])
    with pytest.raises(ValueError):
        update_map(b, scans, boxes[:-1], bounds, order=[0])


def test_scan_reach_is_bounded():
    """A return beyond MAX_SPAN_TILES tiles a side (1e5 m at 5 cm) is refused by both paths
    instead of traversing ~10^9 tiles, and so is a pose beyond the tile index; the same scan
    without them maps."""
    r = np.array([2.0, 1e5, 3.0], np.float32)
    v = np.ones(3, np.bool_)
    box = np.array([0.0, 0.1, 0.0, 0.1, 0.0, 0.05])
    for f in (K.scan_cells, K.scan_cells_reference):
        with pytest.raises(ValueError, match="4096 tiles"):
            f(r, v, -0.1, 0.1, box, 0.01, 0.0, 0.0, 0.05, True)
        v2 = v.copy()
        v2[1] = False
        assert len(f(r, v2, -0.1, 0.1, box, 0.01, 0.0, 0.0, 0.05, True)[2]) > 0
        # a pose beyond the tile index's int32 coordinates (corrupt odometry): refused, not wrapped
        far = box + np.array([1e12, 1e12, 0.0, 0.0, 0.0, 0.0])
        with pytest.raises(ValueError, match="2\\^30 tiles"):
            f(r, v2, -0.1, 0.1, far, 0.01, 0.0, 0.0, 0.05, True)


def test_bench_lidar_map_runs_and_checks(capsys):
    """The benchmark on a short log: the fast path against the reference (same map, old beams and
    counts) and against the truth of the simulated log, both reported OK (the timing verdict is
    the benchmark's business)."""
    from bench import bench_lidar_map as B

    B.main(["--scans", "25", "--repeat", "1"])
    out = capsys.readouterr().out
    assert out.count("same map, old beams and counts: OK") == 2
    assert "P_OBSTACLE^k ∪ P_OLD^k: OK" in out
    assert "P_EMPTY cells meet a wall: OK" in out and "map_union_free added" in out
    assert "load average" in out and "beams/s" in out


def test_fast_update_log_several_chunks_of_tiles():
    """A fine grid where a scan's tiles span several chunks (the fast path visits up to
    ``_CHUNK`` tiles together, level by level): the reference's map, tiles in the same order."""
    rng = np.random.default_rng(5)
    segs, room = random_world(rng)
    poses = np.array([random_pose(rng, segs, room) for _ in range(3)])
    scans = ray_scans(rng, segs, poses, (0.1, 0.0, 0.0), "urg", 0.03, 0.01)
    bounds = LidarBounds(0.03, 0.01, 0.0)
    boxes = np.array([random_box(rng, p, 0.1, math.radians(1)) for p in poses])
    eps = 0.015
    sb = sensor_boxes(boxes, scans.mount)[0]
    hi = max(range_bounds(float(z), 0.03, 0.01)[1] for z in scans.ranges[scans.valid])
    tx0, tx1, ty0, ty1 = K._tile_range(*sb[:4], hi, eps)
    assert (tx1 - tx0 + 1) * (ty1 - ty0 + 1) > 2 * K._CHUNK
    new, ref = TileMap(eps), TileMap(eps)
    a = _run_log(K.update_log, new, scans, boxes, bounds, np.arange(len(scans)), True, True)
    b = _run_log(K.update_log_reference, ref, scans, boxes, bounds, np.arange(len(scans)), True, True)
    _same_maps(new, ref)
    assert new.n > K._CHUNK
    assert np.array_equal(a[0], b[0])
    assert np.array_equal(a[1][:, 1:5], b[1][:, 1:5])

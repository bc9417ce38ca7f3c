"""Relative pose enclosures as part of the result (``Result.relative``: HDF5 round trip, checks)
and their use by ``report --relations``: the relative enclosure met with what the two global
boxes allow, inverted and chained ones (soundness with hypothesis, truth in extended
precision), the source and widths reported, and a simulated keyframes run end to end."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.errors import IvslamError
from ivslam_cli.report.relations import (
    SOURCES,
    Relations,
    chain_enclosures,
    check_relations,
    compose_enclosure,
    invert_enclosure,
    meet_enclosures,
    relations_dict,
    render_relations_text,
)
from ivslam_cli.results.example import example_result
from ivslam_cli.results.hdf5 import read_result, write_result
from ivslam_cli.results.model import RELATIVE_DEFINITION, Poses, RelativePoses, box_is_empty
from tests.helpers.hyp import examples
from tests.helpers.results import assert_same
from tests.helpers.strategies import pose_box_around

LD = np.longdouble


# ---------------------------------------------------------------- truth in extended precision
def _ld(p):
    return [LD(v) for v in p]


def _rel_ld(p1, p2):
    """Pose p2 in the frame of pose p1."""
    x1, y1, t1 = _ld(p1)
    x2, y2, t2 = _ld(p2)
    c, s = np.cos(t1), np.sin(t1)
    dx, dy = x2 - x1, y2 - y1
    return [c * dx + s * dy, -s * dx + c * dy, t2 - t1]


def _inv_ld(p):
    x, y, t = _ld(p)
    c, s = np.cos(t), np.sin(t)
    return [-(c * x + s * y), s * x - c * y, -t]


def _compose_ld(p, r):
    x1, y1, t1 = _ld(p)
    x2, y2, t2 = _ld(r)
    c, s = np.cos(t1), np.sin(t1)
    return [x1 + c * x2 - s * y2, y1 + s * x2 + c * y2, t1 + t2]


def _in(enc, t) -> bool:
    return all(LD(enc[d, 0]) <= t[d] <= LD(enc[d, 1]) for d in range(3))


def _angle_in(lo, hi, t) -> bool:
    """t + 2πn in [lo, hi] for some n (extended precision)."""
    two_pi = 2 * np.pi * LD(1)
    n = np.ceil((LD(lo) - t) / two_pi)
    return any(LD(lo) <= t + two_pi * (n + d) <= LD(hi) for d in (-1, 0, 1))


coord = st.floats(-100, 100, allow_nan=False, allow_infinity=False)
small = st.floats(-3, 3, allow_nan=False, allow_infinity=False)
angle = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
half = st.one_of(st.just(0.0), st.floats(0, 1e-6), st.floats(0, 0.3), st.floats(0, 20))
ahalf = st.one_of(st.just(0.0), st.floats(0, 1e-6), st.floats(0, 0.2), st.floats(0, 4.0))


def box_around(c=coord):
    """A pose (float64) and a box holding it anywhere (not only at its centre)."""
    return pose_box_around(c, angle, half, ahalf)


# ---------------------------------------------------------------- kernels: soundness
@settings(max_examples=examples(ci=400))
@given(box_around(), st.sampled_from([1, 2, 16]))
def test_inverse_holds_the_inverse_pose(pb, slices):
    p, box = pb
    enc = invert_enclosure(box[None], slices)[0]
    assert _in(enc, _inv_ld(p))


@settings(max_examples=examples(ci=400))
@given(box_around(), box_around(small), st.sampled_from([1, 2, 16]))
def test_composition_holds_the_composed_pose(pb, rb, slices):
    (p, bp), (r, br) = pb, rb
    enc = compose_enclosure(bp[None], br[None], slices)[0]
    assert _in(enc, _compose_ld(p, r))


@settings(max_examples=examples(ci=200))
@given(box_around(), st.integers(0, 2**31 - 1))
def test_inverse_and_composition_hold_every_pose_of_the_boxes(pb, seed):
    """Not only the drawn pose: random poses anywhere in the boxes (corners included)."""
    _, box = pb
    rng = np.random.default_rng(seed)
    rbox = np.array([[-0.4, 0.9], [-1.2, -0.3], [0.2, 0.7]])
    inv = invert_enclosure(box[None])[0]
    comp = compose_enclosure(box[None], rbox[None])[0]
    for _ in range(30):
        f = rng.integers(0, 3, 3) / 2.0 if rng.random() < 0.3 else rng.random(3)
        q = box[:, 0] + f * (box[:, 1] - box[:, 0])
        q = np.where(np.isfinite(q), q, box[:, 0])
        r = rbox[:, 0] + rng.random(3) * (rbox[:, 1] - rbox[:, 0])
        assert _in(inv, _inv_ld(q))
        assert _in(comp, _compose_ld(q, r))


def test_inverse_and_composition_are_tight_for_points_and_propagate_empty():
    p = np.array([[1.0, 1.0], [2.0, 2.0], [0.5, 0.5]])
    inv = invert_enclosure(p[None])[0]
    assert np.all(inv[:, 1] - inv[:, 0] < 1e-14)
    # p ⊕ p⁻¹ = identity
    ident = compose_enclosure(p[None], inv[None])[0]
    assert np.all(np.abs(ident) < 1e-14)
    empty = np.array([[np.inf, -np.inf], [0.0, 1.0], [0.0, 1.0]])
    assert box_is_empty(invert_enclosure(empty[None]))[0]
    assert box_is_empty(compose_enclosure(empty[None], p[None]))[0]
    assert box_is_empty(compose_enclosure(p[None], empty[None]))[0]
    with pytest.raises(ValueError):
        compose_enclosure(np.zeros((2, 3, 2)), np.zeros((1, 3, 2)))


def test_meet_headings_modulo_two_pi():
    a = np.array([[0.0, 2.0], [0.0, 2.0], [0.1, 0.3]])
    b = np.array([[1.0, 3.0], [-1.0, 1.0], [0.2 + 2 * math.pi, 0.5 + 2 * math.pi]])
    m = meet_enclosures(a[None], b[None])[0]
    assert m[:2].tolist() == [[1.0, 2.0], [0.0, 1.0]]
    assert m[2, 0] == pytest.approx(0.2) and m[2, 1] == pytest.approx(0.3)
    c = b.copy()
    c[2] = [1.0, 1.5]  # headings disjoint: empty
    assert box_is_empty(meet_enclosures(a[None], c[None]))[0]


def _compose_all_ld(rels):
    t = rels[0]
    for r in rels[1:]:
        t = _compose_ld_exact(t, r)
    return t


def _compose_ld_exact(p, r):
    x1, y1, t1 = p
    c, s = np.cos(t1), np.sin(t1)
    return [x1 + c * r[0] - s * r[1], y1 + s * r[0] + c * r[1], t1 + r[2]]


@st.composite
def chain(draw):
    """Relative poses along a chain 0 → 1 → … → n: hop k is a box of (k-1, k) or, reversed, of
    (k, k-1), holding a drawn pose q_k. Returns the truth of (0, n) and of (n, 0) in extended
    precision: hop by hop q_k where the box is used as given, q_k⁻¹ where it is inverted."""
    n = draw(st.integers(1, 6))
    pairs, boxes, fwd, bwd = [], [], [], []
    for k in range(1, n + 1):
        q, box = draw(box_around(small))
        if draw(st.booleans()):
            pairs.append((k - 1, k))
            fwd.append(_ld(q))
            bwd.append(_inv_ld(q))
        else:
            pairs.append((k, k - 1))
            fwd.append(_inv_ld(q))
            bwd.append(_ld(q))
        boxes.append(box)
    order = draw(st.permutations(range(n)))
    rp = RelativePoses(pairs=np.array([pairs[i] for i in order], np.int64).reshape(-1, 2),
                       box=np.array([boxes[i] for i in order]).reshape(-1, 3, 2))
    return n, rp, _compose_all_ld(fwd), _compose_all_ld(bwd[::-1])


@settings(max_examples=examples(ci=300))
@given(chain())
def test_chains_hold_the_composed_truth(ch):
    n, rp, truth, truth_back = ch
    enc, src, hops = chain_enclosures(rp, np.array([0]), np.array([n]), max_hops=n)
    assert _in(enc[0], truth)
    assert int(hops[0]) == n
    direct = rp.pairs.tolist()
    assert SOURCES[src[0]] == ("chained" if n > 1 else ("relative" if [0, 1] in direct else "inverted"))
    # the other way round
    back, _, _ = chain_enclosures(rp, np.array([n]), np.array([0]), max_hops=n)
    assert _in(back[0], truth_back)
    # one hop short: not reached, unbounded
    if n > 1:
        enc, src, hops = chain_enclosures(rp, np.array([0]), np.array([n]), max_hops=n - 1)
        assert src[0] == 0 and hops[0] == 0 and np.all(np.isinf(enc[0]))


def test_direct_and_reversed_enclosures_of_one_pair_are_met():
    given = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 0.2]])
    reversed_ = np.array([[-0.6, -0.5], [-0.6, -0.5], [-0.1, 0.0]])  # pose 0 in the frame of 1
    rp = RelativePoses(pairs=np.array([[0, 1], [1, 0]]), box=np.stack([given, reversed_]))
    enc, src, hops = chain_enclosures(rp, np.array([0, 1]), np.array([1, 0]))
    inv = invert_enclosure(reversed_[None])[0]
    assert SOURCES[src[0]] == "relative" and SOURCES[src[1]] == "relative" and hops.tolist() == [1, 1]
    assert np.all(enc[0, :, 1] - enc[0, :, 0] <= np.minimum(given[:, 1] - given[:, 0], inv[:, 1] - inv[:, 0]) + 1e-12)
    # not connected: unbounded, source 0
    enc, src, _ = chain_enclosures(rp, np.array([0]), np.array([2]))
    assert src[0] == 0 and np.all(np.isinf(enc[0]))


# ---------------------------------------------------------------- the relations check
def _line(n=6, half=50.0):
    """True poses along a curve; global boxes ``half`` wide around them (drift)."""
    c = np.array([[0.3 * k, 0.1 * k * k, 0.2 * k - 0.4] for k in range(n)])
    box = np.stack([c - half, c + half], axis=-1)
    box[:, 2] = np.stack([c[:, 2] - 1.0, c[:, 2] + 1.0], axis=-1)
    return Poses(stamp=np.arange(n, dtype=float), box=box), c


def _relations(c, pairs):
    rel = np.array([[float(v) for v in _rel_ld(c[a], c[b])] for a, b in pairs])
    return Relations(path="mem", t1=np.array([float(a) for a, _ in pairs]),
                     t2=np.array([float(b) for _, b in pairs]), rel=rel)


def _tight(c, a, b, h=0.01):
    t = np.array([float(v) for v in _rel_ld(c[a], c[b])])
    return np.stack([t - h, t + h], axis=-1)


def test_relations_check_uses_the_tight_relative_enclosure():
    poses, c = _line()
    rp = RelativePoses(pairs=np.array([[0, 1], [1, 2], [4, 3]]),
                       box=np.stack([_tight(c, 0, 1), _tight(c, 1, 2), _tight(c, 4, 3)]))
    rel = _relations(c, [(0, 1), (3, 4), (0, 2), (2, 5)])
    rc = check_relations(poses, rel, relative=rp)
    assert rc.checked == 4 and rc.contained == 4 and rc.sound
    assert [SOURCES[s] for s in rc.source] == ["relative", "inverted", "chained", "global"]
    assert rc.hops.tolist() == [1, 1, 2, 0]
    w, wg = rc.widths(), rc.widths(rc.global_enclosure)
    assert np.all(w[0] <= 0.02 + 1e-12)  # the tight one
    assert np.all(w[1] < 0.05) and np.all(w[2] < 0.1)  # inverted, chained: a little wider (rotation)
    assert np.all(wg[:, :2] > 90) and np.array_equal(w[3], wg[3])  # global boxes: 100 m wide
    # without the relative enclosures: the global ones, as before
    rc0 = check_relations(poses, rel)
    assert np.array_equal(rc0.enclosure, rc.global_enclosure) and not np.any(rc0.source)
    # the report: counts per source and the tight widths
    d = relations_dict(rc)
    json.dumps(d, allow_nan=False)
    assert d["used_relative"] == 3 and d["relative_enclosures"] == 3
    bs = d["by_source"]
    assert {k: v["count"] for k, v in bs.items()} == {"global": 1, "relative": 1, "inverted": 1, "chained": 1}
    assert bs["relative"]["width"]["x"]["median"] <= 0.02 + 1e-12
    assert bs["relative"]["global_boxes_width"]["x"]["median"] > 90
    assert [e["source"] for e in d["list"]] == ["relative", "inverted", "chained", "global"]
    text = render_relations_text(rc)
    assert "sources:  1 from the two global boxes only, 3 met with relative enclosures (1 direct, 1 inverted, " \
           "1 chained" in text and "two global boxes alone" in text
    # max_hops = 1: no chain
    rc1 = check_relations(poses, rel, relative=rp, max_hops=1)
    assert [SOURCES[s] for s in rc1.source] == ["relative", "inverted", "global", "global"]


def test_relations_check_relative_enclosure_that_misses_the_truth_is_a_failure():
    """A wrong relative enclosure is not hidden by the wide global boxes: the meet is checked."""
    poses, c = _line()
    wrong = _tight(c, 0, 1) + 0.5
    rc = check_relations(poses, _relations(c, [(0, 1)]), relative=RelativePoses(np.array([[0, 1]]), wrong[None]))
    assert rc.contained == 0 and not rc.sound and "(relative)" in rc.failures[0]


@settings(max_examples=examples(ci=60))
@given(st.integers(0, 2**31 - 1), st.integers(3, 8))
def test_relations_check_with_random_relative_boxes_keeps_the_truth(seed, n):
    """Random trajectories, random boxes around them, random relative boxes (given or
    reversed) around the true relative poses: every relation inside whatever the source."""
    rng = np.random.default_rng(seed)
    c = np.column_stack([rng.uniform(-20, 20, n), rng.uniform(-20, 20, n), rng.uniform(-7, 7, n)])
    h = rng.choice([0.0, 0.01, 1.0, 30.0], (n, 3)) * rng.random((n, 3))
    off = rng.random((n, 3))
    # (at least 1e-9 wide: the check adds 2πn to the true heading in float64, an enclosure one
    # ulp wide in another branch would be missed by the check, not by the enclosure)
    box = np.stack([c - 2 * h * off - 1e-9, c + 2 * h * (1 - off) + 1e-9], axis=-1)
    box[:, 2] += rng.integers(-2, 3, (n, 1)) * 2 * math.pi  # headings in other branches
    pairs, boxes = [], []
    for _ in range(int(rng.integers(1, 2 * n))):
        a, b = (int(v) for v in rng.choice(n, 2, replace=False))
        t = np.array([float(v) for v in _rel_ld(c[a], c[b])])
        hh = rng.choice([0.0, 1e-3, 0.1, 1.0]) * rng.random(3)
        f = rng.random(3)
        bx = np.stack([t - 2 * hh * f - 1e-12, t + 2 * hh * (1 - f) + 1e-12], axis=-1)
        bx[2] += float(rng.integers(-1, 2)) * 2 * math.pi
        pairs.append((a, b))
        boxes.append(bx)
    rp = RelativePoses(np.array(pairs, np.int64), np.array(boxes))
    ends = [(a, b) for a in range(n) for b in range(n) if a != b]
    rc = check_relations(Poses(np.arange(n, dtype=float), box), _relations(c, ends), relative=rp, max_hops=n)
    assert rc.checked == len(ends)
    assert rc.sound, rc.failures[:3]
    assert np.any(rc.source > 0)


# ---------------------------------------------------------------- the result file
def _with_relative(r):
    n = len(r.poses)
    pairs = np.array([[0, k] for k in range(1, n)] + [[n - 1, 2]], np.int64)
    box = np.zeros((pairs.shape[0], 3, 2))
    box[..., 0] = -0.1 * np.arange(1, pairs.shape[0] + 1)[:, None]
    box[..., 1] = 0.2
    box[-1, 2] = [-np.inf, np.inf]  # an unbounded heading is allowed
    r.relative = RelativePoses(pairs=pairs, box=box)
    return r


def test_round_trip_with_and_without_relative(tmp_path):
    r = _with_relative(example_result("lidar"))
    write_result(tmp_path / "r.h5", r)
    back = read_result(tmp_path / "r.h5")
    assert_same(r, back)
    assert back.relative.definition == RELATIVE_DEFINITION and len(back.relative) == len(r.poses)
    with h5py.File(tmp_path / "r.h5", "r") as f:
        assert f["relative/pairs"].dtype == np.int64 and f["relative/box"].shape == (len(r.poses), 3, 2)
    # without: no group, read back as None
    r0 = example_result("lidar")
    assert r0.relative is None
    write_result(tmp_path / "r0.h5", r0)
    with h5py.File(tmp_path / "r0.h5", "r") as f:
        assert "relative" not in f
    assert read_result(tmp_path / "r0.h5").relative is None
    # empty (a keyframes run with one scan): kept as an empty group
    r.relative = RelativePoses(np.zeros((0, 2), np.int64), np.zeros((0, 3, 2)))
    write_result(tmp_path / "e.h5", r, force=True)
    assert len(read_result(tmp_path / "e.h5").relative) == 0


@pytest.mark.parametrize("bad,what", [
    (lambda rp: rp.pairs.__setitem__((0, 1), 6), "pose rows"),
    (lambda rp: rp.pairs.__setitem__((1, 0), -1), "pose rows"),
    (lambda rp: rp.box.__setitem__((2, 0), [0.3, 0.2]), "lo <= hi"),
    (lambda rp: rp.box.__setitem__((2, 1, 0), np.nan), "lo <= hi"),
])
def test_validate_rejects_bad_relative_enclosures(tmp_path, bad, what):
    r = _with_relative(example_result("lidar"))
    bad(r.relative)
    with pytest.raises(ValueError, match=what):
        write_result(tmp_path / "r.h5", r)
    assert not (tmp_path / "r.h5").exists()
    # the same in a file: a one-line corrupt-result error naming it
    good = _with_relative(example_result("lidar"))
    write_result(tmp_path / "g.h5", good)
    with h5py.File(tmp_path / "g.h5", "r+") as f:
        f["relative/pairs"][...] = r.relative.pairs
        f["relative/box"][...] = r.relative.box
    with pytest.raises(IvslamError, match=what) as e:
        read_result(tmp_path / "g.h5")
    assert "g.h5" in str(e.value) and "\n" not in str(e.value)


def test_validate_shapes_and_needs_poses(tmp_path):
    r = _with_relative(example_result("lidar"))
    r.relative.box = r.relative.box[:, :2]
    with pytest.raises(ValueError, match=r"\(R, 3, 2\)"):
        r.validate()
    r = _with_relative(example_result("lidar"))
    r.poses = None
    with pytest.raises(ValueError, match="needs the poses"):
        r.validate()
    r = _with_relative(example_result("lidar"))
    write_result(tmp_path / "r.h5", r)
    with h5py.File(tmp_path / "r.h5", "r+") as f:
        del f["relative/box"]
        f["relative"].create_dataset("box", data=np.zeros((3, 6)))
    with pytest.raises(IvslamError, match="corrupt"):
        read_result(tmp_path / "r.h5")


def test_schema_documents_the_relative_group(tmp_path):
    from pathlib import Path

    from ivslam_cli.results import hdf5

    doc = (Path(hdf5.__file__).parent / "SCHEMA.md").read_text()
    assert "**`/relative`**" in doc
    write_result(tmp_path / "r.h5", _with_relative(example_result("lidar")))
    with h5py.File(tmp_path / "r.h5", "r") as f:
        names = set(f["relative"]) | set(f["relative"].attrs)
    assert names == {"pairs", "box", "definition"}
    section = doc.split("**`/relative`**", 1)[1].split("\n**`/", 1)[0]
    assert all(f"`{n}`" in section for n in names)


def test_report_shows_the_relative_enclosures(tmp_path, cli_run):
    r = _with_relative(example_result("lidar"))
    write_result(tmp_path / "r.h5", r)
    res = cli_run("report", tmp_path / "r.h5")
    assert res.exit_code == 0 and f"relative     {len(r.relative)} enclosures" in res.output
    res = cli_run("report", tmp_path / "r.h5", "--json")
    d = json.loads(res.output)["relative"]
    assert d["count"] == len(r.relative) and d["width"]["theta"]["max"] == "inf"
    assert d["width"]["y"]["median"] == pytest.approx(0.2 + 0.1 * np.median(np.arange(1, len(r.relative) + 1)))
    write_result(tmp_path / "r0.h5", example_result("lidar"))
    assert "relative" not in json.loads(cli_run("report", tmp_path / "r0.h5", "--json").output)
    assert "relative     " not in cli_run("report", tmp_path / "r0.h5").output


# ---------------------------------------------------------------- a simulated submap run, end to end
def test_simulated_submap_run_relations_use_the_relative_enclosures(tmp_path, cli_run):
    """run --mode lidar (submaps) → the result holds ``relative`` (every scan in its anchor's
    frame) → report --relations on relations made from the truth between anchors and scans:
    every one inside, those of an (anchor, scan) pair from the relative enclosure and tighter."""
    from ivslam_cli.config import resolve_config
    from ivslam_cli.simulate import SimConfig, simulate
    from ivslam_cli.slam import run_pipeline

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=4, steps=60))
    cfg = resolve_config(None, {"lidar.submap_distance": 1.0}, log_bounds=log.bounds)
    res = run_pipeline(log, cfg, "lidar")
    assert res.relative is not None and len(res.relative) > 0 and len(res.submaps) >= 2
    pairs = res.relative.pairs
    write_result(tmp_path / "r.h5", res)
    # relations from the truth: every relative pair, its reverse, and a chain through a keyframe
    tr = log.truth
    p = tr.pose[np.searchsorted(tr.pose_stamp, res.poses.stamp)]
    s = res.poses.stamp
    ends = [(int(a), int(b)) for a, b in pairs] + [(int(b), int(a)) for a, b in pairs[:5]]
    kf = sorted({int(a) for a, _ in pairs})
    if len(kf) >= 3:
        ends.append((kf[0], kf[2]))
    # the truth in the result's frame (the first pose's): relations are relative, frame-free
    lines = "\n".join(f"{s[a]:.6f} {s[b]:.6f} " + " ".join(f"{float(v):.12g}" for v in _rel_ld(p[a], p[b])[:2])
                      + f" 0 0 0 {float(_rel_ld(p[a], p[b])[2]):.12g}" for a, b in ends)
    (tmp_path / "rel.txt").write_text(lines + "\n")
    out = cli_run("report", tmp_path / "r.h5", "--relations", tmp_path / "rel.txt", "--json")
    assert out.exit_code == 0, out.output
    d = json.loads(out.output)["relations"]
    assert d["matched"] == len(ends) and d["inside"] == len(ends) and d["sound"]
    assert d["used_relative"] == len(ends)
    bs = d["by_source"]
    assert bs["relative"]["count"] == pairs.shape[0] and bs["inverted"]["count"] == 5
    w, wg = bs["relative"]["width"], bs["relative"]["global_boxes_width"]
    assert all(w[k]["median"] <= wg[k]["median"] for k in ("x", "y", "theta"))
    text = cli_run("report", tmp_path / "r.h5", "--relations", tmp_path / "rel.txt").output
    assert f"inside:   {len(ends)}/{len(ends)}" in text and "sources:  0 from the two global boxes only" in text

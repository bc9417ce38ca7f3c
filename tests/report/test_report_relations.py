"""`ivslam report --relations`: the relative-pose enclosure (soundness with hypothesis, tightness),
relations files (formats, one-line errors), stamp matching, the check and the CLI on a
hand-made result. The real Intel run is in test_intel_relations.py."""

from __future__ import annotations

import gzip
import json
import lzma
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.errors import IvslamError
from ivslam_cli.report.relations import (
    DEFAULT_TOL,
    Relations,
    check_relations,
    match_stamps,
    read_relations,
    relations_dict,
    relative_enclosure,
    render_relations_text,
)
from ivslam_cli.results.example import example_result
from ivslam_cli.results.hdf5 import write_result
from ivslam_cli.results.model import Poses
from tests.helpers.hyp import examples
from tests.helpers.strategies import pose_box_around

LD = np.longdouble


def _true_relative(p1, p2):
    """The relative pose in extended precision (its error is far below the enclosure's rounding)."""
    x1, y1, t1 = (LD(v) for v in p1)
    x2, y2, t2 = (LD(v) for v in p2)
    c, s = np.cos(t1), np.sin(t1)
    dx, dy = x2 - x1, y2 - y1
    return c * dx + s * dy, -s * dx + c * dy, t2 - t1


def _inside(enc, p1, p2) -> bool:
    t = _true_relative(p1, p2)
    return all(LD(enc[d, 0]) <= t[d] <= LD(enc[d, 1]) for d in range(3))


coord = st.floats(-200, 200, allow_nan=False, allow_infinity=False)
angle = st.floats(-20, 20, allow_nan=False, allow_infinity=False)
half = st.one_of(st.just(0.0), st.floats(0, 1e-6), st.floats(0, 0.5), st.floats(0, 50))
ahalf = st.one_of(st.just(0.0), st.floats(0, 1e-6), st.floats(0, 0.3), st.floats(0, 4.0))


def box_around():
    """A true pose and a box holding it (the truth anywhere in the box, not only its centre)."""
    return pose_box_around(coord, angle, half, ahalf)


@settings(max_examples=examples(ci=400))
@given(box_around(), box_around(), st.sampled_from([1, 2, 16, 64]))
def test_relative_enclosure_holds_the_true_relative_pose(a, b, slices):
    (p1, b1), (p2, b2) = a, b
    enc = relative_enclosure(b1[None], b2[None], slices)[0]
    assert np.all(enc[:, 0] <= enc[:, 1])
    assert _inside(enc, p1, p2), (p1, b1, p2, b2, enc)


@given(box_around(), box_around(), st.integers(2, 40))
def test_relative_enclosure_every_pose_of_the_boxes(a, b, seed):
    """Poses drawn all over the two boxes (corners included) stay inside the enclosure."""
    (_, b1), (_, b2) = a, b
    rng = np.random.default_rng(seed)
    enc = relative_enclosure(b1[None], b2[None])[0]
    for _ in range(20):
        u, v = rng.random(3), rng.random(3)
        u[rng.random(3) < 0.3] = rng.integers(0, 2)  # corners and faces
        p1 = b1[:, 0] + u * (b1[:, 1] - b1[:, 0])
        p2 = b2[:, 0] + v * (b2[:, 1] - b2[:, 0])
        p1 = np.clip(p1, b1[:, 0], b1[:, 1])
        p2 = np.clip(p2, b2[:, 0], b2[:, 1])
        assert _inside(enc, p1, p2)


def test_relative_enclosure_is_tight_for_point_boxes_and_slices_help():
    p1, p2 = np.array([1.0, 2.0, 0.7]), np.array([4.0, -1.0, 2.0])
    pt = lambda p: np.stack([p, p], axis=1)  # noqa: E731
    enc = relative_enclosure(pt(p1)[None], pt(p2)[None])[0]
    t = [float(v) for v in _true_relative(p1, p2)]
    assert np.all(enc[:, 1] - enc[:, 0] < 1e-12)
    np.testing.assert_allclose(enc.mean(axis=1), t, atol=1e-12)
    # a heading interval of 1 rad: slicing it gives a narrower (still sound) enclosure
    b1 = pt(p1)
    b1[2] = (0.2, 1.2)
    w1 = np.diff(relative_enclosure(b1[None], pt(p2)[None], 1)[0], axis=1).ravel()
    w16 = np.diff(relative_enclosure(b1[None], pt(p2)[None], 16)[0], axis=1).ravel()
    assert np.all(w16[:2] <= w1[:2]) and w16[1] < 0.5 * w1[1] and w16[2] == w1[2]
    # the length bound: whatever the heading, |Δ| <= |p2 − p1|
    b1[2] = (-100.0, 100.0)
    enc = relative_enclosure(b1[None], pt(p2)[None])[0]
    r = math.hypot(3.0, 3.0)
    assert enc[0, 1] == pytest.approx(r) and enc[1, 0] == pytest.approx(-r)


def test_relative_enclosure_empty_and_unbounded():
    empty = np.array([[np.inf, -np.inf], [0, 1], [0, 1]], float)
    ok = np.array([[0, 1], [0, 1], [0, 1]], float)
    out = relative_enclosure(np.stack([empty, ok]), np.stack([ok, ok]))
    assert np.all(out[0, :, 0] > out[0, :, 1])  # empty in, empty out
    assert np.all(out[1, :, 0] <= out[1, :, 1])
    unb = np.array([[-np.inf, np.inf], [0, 1], [-np.inf, np.inf]], float)
    out = relative_enclosure(unb[None], ok[None])[0]
    assert out[0, 0] == -np.inf and out[0, 1] == np.inf and out[2, 0] == -np.inf
    with pytest.raises(ValueError):
        relative_enclosure(np.zeros((2, 3, 2)), np.zeros((1, 3, 2)))


# ----------------------------------------------------------------- files
LINES = ["976052905.167303 976052911.885496 -0.056990 -0.128430 0.000000 0.000000 0.000000 -1.682210",
         "# a comment", "",
         "1.5 2.5 0.1 0.2 0 0 0 0.3  # trailing comment"]


@pytest.mark.parametrize("kind", ["plain", "xz", "gz"])
def test_read_relations(tmp_path, kind):
    text = "\n".join(LINES) + "\n"
    p = tmp_path / f"r.{kind}"
    if kind == "xz":
        p.write_bytes(lzma.compress(text.encode()))
    elif kind == "gz":
        p.write_bytes(gzip.compress(text.encode()))
    else:
        p.write_text(text)
    r = read_relations(p)
    assert len(r) == 2
    assert r.t1[0] == 976052905.167303 and r.t2[1] == 2.5
    np.testing.assert_array_equal(r.rel, [[-0.05699, -0.12843, -1.68221], [0.1, 0.2, 0.3]])


@pytest.mark.parametrize("content,needle", [
    ("", "no relations"),
    ("# only a comment\n\n", "no relations"),
    ("1 2 3 4 5 6 7\n", "line 1: 7 fields"),
    ("1 2 0 0 0 0 0 0\n1 2 0 0 0 0 0 0 9\n", "line 2: 9 fields"),
    ("1 2 0 x 0 0 0 0\n", "line 1: not a number"),
    ("1 2 0 nan 0 0 0 0\n", "line 1: NaN or infinite"),
    ("1 2 0 0 0 0 0 inf\n", "line 1: NaN or infinite"),
])
def test_bad_relations_files(tmp_path, content, needle):
    p = tmp_path / "bad.relations"
    p.write_text(content)
    with pytest.raises(IvslamError) as exc:
        read_relations(p)
    msg = str(exc.value)
    assert needle in msg and str(p) in msg and "\n" not in msg


def test_bad_relations_files_binary_truncated_missing(tmp_path):
    good = lzma.compress(("\n".join(LINES) + "\n").encode() * 50)
    cases = {"trunc.xz": good[: len(good) // 2], "bin.rel": b"\x00\x01\x02 junk"}
    for name, raw in cases.items():
        p = tmp_path / name
        p.write_bytes(raw)
        with pytest.raises(IvslamError) as exc:
            read_relations(p)
        assert str(p) in str(exc.value) and "\n" not in str(exc.value)
    for p in (tmp_path / "missing.relations", tmp_path):
        with pytest.raises(IvslamError) as exc:
            read_relations(p)
        assert str(p) in str(exc.value)


# ----------------------------------------------------------------- matching and the check
def test_match_stamps_tolerance_and_ambiguity():
    s = np.array([0.0, 1.0, 1.00005, 3.0])
    idx, amb = match_stamps(s, np.array([0.0, 0.00009, 0.0002, 1.00002, 3.0, -1.0]), 1e-4)
    assert idx.tolist() == [0, 0, -1, -1, 3, -1]
    assert amb.tolist() == [False, False, False, True, False, False]
    idx, _ = match_stamps(s, np.array([0.0002]), 1e-3)
    assert idx.tolist() == [0]
    idx, amb = match_stamps(np.zeros(0), np.array([1.0]), 1e-4)
    assert idx.tolist() == [-1] and not amb.any()


def _poses_line(n=6, half=0.3):
    """Robot along x at 1 m/s, heading 0.1, y = 0.5: boxes of half-width ``half`` at stamps 0..n−1."""
    stamp = np.arange(n, dtype=float)
    c = np.stack([stamp, np.full(n, 0.5), np.full(n, 0.1)], axis=1)
    return Poses(stamp=stamp, box=np.stack([c - half, c + half], axis=2)), c


def _rel_from(c, pairs, stamps=None):
    t1, t2, rel = [], [], []
    for a, b in pairs:
        r = [float(v) for v in _true_relative(c[a], c[b])]
        t1.append(float(a) if stamps is None else stamps[a])
        t2.append(float(b) if stamps is None else stamps[b])
        rel.append(r)
    return Relations(path="mem", t1=np.array(t1), t2=np.array(t2), rel=np.array(rel))


def test_check_relations_counts_inside_and_failures():
    poses, c = _poses_line()
    rel = _rel_from(c, [(0, 1), (1, 4), (2, 5)])
    # ends off the poses: one end, none, same pose (0.00002 s off is still pose 3)
    extra = Relations(path="mem", t1=np.array([0.5, 0.5, 3.0]), t2=np.array([2.0, 7.5, 3.00002]),
                      rel=np.zeros((3, 3)))
    both = Relations(path="mem", t1=np.concatenate([rel.t1, extra.t1]), t2=np.concatenate([rel.t2, extra.t2]),
                     rel=np.concatenate([rel.rel, extra.rel]))
    rc = check_relations(poses, both)
    assert (rc.total, rc.checked, rc.one_end, rc.same_pose, rc.ambiguous) == (6, 3, 1, 1, 0)
    assert rc.contained == 3 and rc.sound and not rc.failures
    assert rc.k1.tolist() == [0, 1, 2] and rc.k2.tolist() == [1, 4, 5]
    w = rc.widths()
    assert np.all(w[:, 2] == pytest.approx(1.2))  # two heading intervals of width 0.6
    assert np.all(w[:, :2] > 1.2)  # the positions' widths, rotated
    # a relation whose truth is off: not inside, listed, the check not sound
    bad = Relations(path="mem", t1=rel.t1, t2=rel.t2, rel=rel.rel + np.array([[0, 0, 0], [5.0, 0, 0], [0, 0, 0]]))
    rc = check_relations(poses, bad)
    assert rc.contained == 2 and not rc.sound and len(rc.failures) == 1 and "relation 2 " in rc.failures[0]
    d = relations_dict(rc)
    assert d["soundness"] == "SOUNDNESS FAILURE" and d["inside"] == 2 and d["matched"] == 3
    assert [e["inside"] for e in d["list"]] == [True, False, True]
    assert "SOUNDNESS FAILURE" in render_relations_text(rc)
    json.dumps(d, allow_nan=False)


def test_check_relations_heading_modulo_two_pi_and_tolerance():
    poses, c = _poses_line()
    rel = _rel_from(c, [(0, 2)])
    rel.rel[0, 2] += 2 * math.pi  # the same heading, another branch
    assert check_relations(poses, rel).contained == 1
    rel.rel[0, 2] += 1.0
    assert check_relations(poses, rel).contained == 0
    # stamps 0.5 ms off: not matched by default, matched with --stamp-tol 0.001
    off = Relations(path="mem", t1=np.array([0.0005]), t2=np.array([2.0]), rel=_rel_from(c, [(0, 2)]).rel)
    assert check_relations(poses, off).checked == 0 and DEFAULT_TOL < 0.0005
    assert check_relations(poses, off, tol=1e-3).checked == 1
    with pytest.raises(IvslamError):
        check_relations(poses, off, tol=-1.0)


def test_check_relations_unsorted_pose_stamps():
    poses, c = _poses_line()
    perm = np.array([3, 0, 5, 1, 4, 2])
    shuffled = Poses(stamp=poses.stamp[perm], box=poses.box[perm])
    rc = check_relations(shuffled, _rel_from(c, [(0, 1), (2, 5)]))
    assert rc.checked == 2 and rc.sound
    assert shuffled.stamp[rc.k1].tolist() == [0.0, 2.0] and shuffled.stamp[rc.k2].tolist() == [1.0, 5.0]


# ----------------------------------------------------------------- the command
@pytest.fixture
def example_files(tmp_path):
    res = example_result()
    path = tmp_path / "r.h5"
    write_result(path, res)
    c = np.column_stack([res.poses.stamp, np.full(len(res.poses), 0.5), np.full(len(res.poses), 0.1)])
    rel = _rel_from(c, [(0, 1), (1, 3), (2, 4)], stamps=list(res.poses.stamp))
    lines = [f"{a:.6f} {b:.6f} {r[0]:.9f} {r[1]:.9f} 0 0 0 {r[2]:.9f}" for a, b, r in zip(rel.t1, rel.t2, rel.rel)]
    lines.append("100.0 101.0 0 0 0 0 0 0")  # not on the result's stamps
    rp = tmp_path / "r.relations"
    rp.write_text("\n".join(lines) + "\n")
    return path, rp


def test_cli_report_relations_text_and_json(cli_run, example_files):
    path, rp = example_files
    res = cli_run("report", path, "--relations", rp)
    assert res.exit_code == 0, res.output
    assert "relations:" in res.output and "4 relation(s); 3 with both ends" in res.output
    assert "inside:   3/3" in res.output and "— ok" in res.output
    res = cli_run("report", path, "--relations", rp, "--json")
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    assert d["mode"] and d["relations"]["matched"] == 3 and d["relations"]["inside"] == 3
    assert d["relations"]["sound"] is True and d["relations"]["width"]["x"]["median"] > 0


def test_cli_report_relations_errors(cli_run, example_files, tmp_path):
    path, rp = example_files
    res = cli_run("report", path, "--stamp-tol", "0.01")
    assert res.exit_code != 0 and "--stamp-tol applies to --relations only" in res.output
    bad = tmp_path / "bad.relations"
    bad.write_text("1 2 3\n")
    res = cli_run("report", path, "--relations", bad)
    assert res.exit_code != 0 and str(bad) in res.output and "line 1: 3 fields" in res.output
    assert len(res.output.strip().splitlines()) == 1
    res = cli_run("report", path, "--relations", tmp_path / "nope.relations")
    assert res.exit_code != 0 and "nope.relations" in res.output

"""What a scan's free cones prove (`slam/lidar/free_cones.py`), as the matcher reads them.

`_may_cover` is a cheap necessary condition for `_seg_free` (a rectangle certified free by a
scan's cones): the matcher skips the exact test where it is False, so it must never be False
where the exact test is True, or the matcher would exclude less (looser, never unsound) and no
longer be the matcher the tightness figures describe. Random scans (some beams invalid, short
and long free ranges, up to a 350° span), sensors anywhere with unnormalised headings, and
rectangles around them: wherever the exact test certifies a rectangle, every point of it —
corners, edge midpoints, the far end the matcher tests — passes the quick test. And
`covered_free` certifies only windows the cone model makes free.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.slam.lidar.free_cones import _cover_setup, _may_cover, _seg_free
from tests.helpers.hyp import examples


@st.composite
def _case(draw):
    nb = draw(st.integers(3, 700))
    inc = draw(st.floats(1e-3, 0.03))
    inc = min(inc, 6.1 / (nb - 1))  # spans up to ~350°
    a0 = draw(st.floats(-4.0, 1.0))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    far = draw(st.floats(0.5, 12.0))
    f = np.where(rng.random(nb) < draw(st.sampled_from([0.8, 0.97, 1.0])), far * (1.0 - 0.3 * rng.random(nb) ** 4),
                 rng.uniform(0.05, far, nb))
    f[rng.random(nb) < draw(st.sampled_from([0.0, 0.0, 0.01, 0.2]))] = -1.0
    cx, cy = draw(st.floats(-50.0, 50.0)), draw(st.floats(-50.0, 50.0))
    c = draw(st.floats(-12.0, 12.0))  # headings are not normalised in the tracker
    hw = 0.3 * draw(st.floats(0.0, 1.0)) ** 3
    # a rectangle in front of the sensor, mostly within the scan's span
    beta = a0 + draw(st.floats(-0.05, 1.05)) * (nb - 1) * inc + c
    dist = 0.01 + draw(st.floats(0.0, 1.1)) * far
    phi = draw(st.floats(-math.pi, math.pi))
    ah, ac = 0.6 * draw(st.floats(0.0, 1.0)) ** 3, 0.6 * draw(st.floats(0.0, 1.0)) ** 3
    vx, vy = dist * math.cos(beta), dist * math.sin(beta)
    if draw(st.booleans()):
        # at the boundary: the rectangle along its bearing, every valid beam's free range just
        # beyond its farthest corner
        phi = beta + draw(st.floats(-1e-3, 1e-3))
        gap = draw(st.sampled_from([1e-9, 1e-6, 1e-4, 1e-2]))
        rho = math.hypot(dist + ah, ac)
        f = np.where(f > 0.0, rho * (1.0 + gap) + 1e-9, f)
    ra = inc * draw(st.sampled_from([0.5, 0.5, 0.6, 0.8, 1.1, 0.25]))  # cones that touch, or gaps assumed free
    smin = draw(st.sampled_from([0.0, 0.0, 1e-300, 1e-3, 0.5]))  # every beam from one pose (0), or a sweep
    return f, a0, inc, ra, cx, cy, c, hw, vx, vy, math.cos(phi), math.sin(phi), ah, ac, smin


@settings(max_examples=examples(ci=3000))
@given(_case())
def test_the_quick_rejection_never_rejects_what_the_exact_test_certifies(case):
    f, a0, inc, ra, cx, cy, c, hw, vx, vy, ux, uy, ah, ac, smin = case
    stl, sth = c - hw, c + hw
    if not _seg_free(vx, vy, ux, uy, ah, ac, stl, sth, f, a0, inc, ra, smin):
        return
    ii, acn, mi, ok, rr = _cover_setup(f.shape[0], a0, inc, ra)
    mid = 0.5 * (stl + sth)
    for s in (-1.0, 0.0, 1.0):
        for t in (-1.0, 0.0, 1.0):
            px = cx + vx + s * ah * ux - t * ac * uy
            py = cy + vy + s * ah * uy + t * ac * ux
            assert _may_cover(px, py, cx, cy, mid, f, a0, ii, acn, mi, ok, rr, not smin > 0.0), (s, t)


def test_the_quick_rejection_rejects_points_beyond_the_free_ranges():
    """It is worth its cost: points past a beam's free range, or outside the scan's span, or
    behind an invalid beam are rejected (a test that cannot fail is no test: also the
    converse, a point well inside is not)."""
    nb, a0, inc = 181, -math.pi / 2, math.pi / 180
    f = np.full(nb, 4.0)
    f[100] = -1.0
    ii, acn, mi, ok, rr = _cover_setup(nb, a0, inc, 0.5 * inc)
    assert ok
    for c in (0.0, 2 * math.pi, -6 * math.pi):  # the same heading, unnormalised
        assert _may_cover(3.0, 0.0, 0.0, 0.0, c, f, a0, ii, acn, mi, ok, rr, True)
        assert not _may_cover(4.1, 0.0, 0.0, 0.0, c, f, a0, ii, acn, mi, ok, rr, True)
        assert not _may_cover(-3.0, 0.1, 0.0, 0.0, c, f, a0, ii, acn, mi, ok, rr, True)  # behind: outside the span
        b = a0 + 100.3 * inc
        assert not _may_cover(2.0 * math.cos(b), 2.0 * math.sin(b), 0.0, 0.0, c, f, a0, ii, acn, mi, ok, rr, True)
    # a heading far from the principal turns, or NaN: no shortcut (the exact test decides)
    for c in (1e6, -1e6, math.nan):
        assert _may_cover(4.1, 0.0, 0.0, 0.0, c, f, a0, ii, acn, mi, ok, rr, True)


@st.composite
def _window(draw):
    nb = draw(st.integers(2, 40))
    inc = draw(st.floats(1e-3, 0.05))
    a0 = draw(st.floats(-3.0, 1.0))
    ra = inc * draw(st.sampled_from([0.5, 0.5, 0.5000001, 0.7, 0.95, 1.1, 0.25]))
    f = np.array(draw(st.lists(st.sampled_from([-1.0, 0.5, 1.0, 2.0, 3.0]), min_size=nb, max_size=nb)))
    bl = a0 + draw(st.floats(-1.0, nb)) * inc
    bh = bl + draw(st.floats(0.0, 3.0)) * inc * draw(st.sampled_from([0.01, 0.3, 1.0]))
    rho = draw(st.sampled_from([0.4, 0.9, 1.5, 2.5]))
    return f, a0, inc, ra, bl, bh, rho


@settings(max_examples=examples(ci=3000))
@given(_window())
def test_covered_free_certifies_only_bearings_some_free_cone_holds(case):
    """Wherever a window is certified free to ``rho``, every bearing of it (sampled densely, ends
    included) lies in the cone of a beam free beyond ``rho`` (cones that touch), or between two
    such beams (gaps assumed free): the free space the map kernels prove."""
    from ivslam_cli.slam.lidar.free_cones import covered_free

    f, a0, inc, ra, bl, bh, rho = case
    if not covered_free(f, a0, inc, ra, bl, bh, rho, True):
        return
    centre = a0 + inc * np.arange(f.size)
    ok = f > rho
    tol = 1e-12 * (1.0 + abs(a0) + f.size * inc)  # the float centres' rounding (closed cones that touch)
    for b in np.concatenate([np.linspace(bl, bh, 257), [bl, bh]]):
        if ra >= 0.5 * inc:
            assert ok[np.abs(b - centre) <= ra + tol].any(), b
        else:
            i = math.floor((b - a0) / inc)
            assert 0 <= i and i + (b > centre[i]) < f.size and ok[i] and ok[min(i + 1, f.size - 1)], b


def test_covered_free_needs_only_the_cone_that_holds_a_narrow_window():
    """A window inside one beam's cone (cones that touch) needs that beam alone, not its invalid
    neighbour: the rule the exact two-scan test keeps (a test that cannot fail is no test: the
    same window across the neighbour's cone is not certified)."""
    from ivslam_cli.slam.lidar.free_cones import covered_free

    inc = 0.01
    f = np.array([2.0, 2.0, -1.0, 2.0])
    a1 = 0.0 + 1 * inc
    assert covered_free(f, 0.0, inc, 0.5 * inc, a1 + 0.1 * inc, a1 + 0.4 * inc, 1.5, True)
    assert covered_free(f, 0.0, inc, 0.5 * inc, a1 - 0.4 * inc, a1 + 0.4 * inc, 1.5, True)
    assert not covered_free(f, 0.0, inc, 0.5 * inc, a1 + 0.1 * inc, a1 + 0.6 * inc, 1.5, True)
    assert not covered_free(f, 0.0, inc, 0.5 * inc, a1 + 0.1 * inc, a1 + 0.4 * inc, 2.5, True)
    # gaps assumed free (narrower cones): the two beams around the window
    assert not covered_free(f, 0.0, inc, 0.25 * inc, a1 + 0.1 * inc, a1 + 0.4 * inc, 1.5, True)
    assert covered_free(f, 0.0, inc, 0.25 * inc, 0.1 * inc, 0.4 * inc, 1.5, True)


def test_covered_free_needs_a_free_cone_at_each_bearing_not_every_cone_it_meets():
    """Overlapping cones (``ra = 0.8 inc``): a window that enters a short beam's cone where its
    neighbour's cone also holds it is certified by the neighbour (each bearing lies in a cone
    free beyond ``rho``); reaching the bearings only the short beam's cone holds, it is not.
    With ``ra > inc`` the short beam's neighbours bridge it."""
    from ivslam_cli.slam.lidar.free_cones import covered_free

    inc = 0.01
    f = np.array([2.0, 2.0, 0.5, 2.0, 2.0])  # beam 2 (at 0.02) is free only to 0.5
    ra = 0.8 * inc  # beam 2's cone [0.012, 0.028]; only it holds [0.018, 0.022]
    assert covered_free(f, 0.0, inc, ra, 0.005, 0.016, 1.5, True)
    assert covered_free(f, 0.0, inc, ra, 0.024, 0.035, 1.5, True)
    assert not covered_free(f, 0.0, inc, ra, 0.005, 0.019, 1.5, True)
    assert not covered_free(f, 0.0, inc, ra, 0.021, 0.035, 1.5, True)
    assert not covered_free(f, 0.0, inc, ra, 0.005, 0.035, 1.5, True)
    assert covered_free(f, 0.0, inc, ra, 0.005, 0.035, 0.4, True)
    assert covered_free(f, 0.0, inc, 1.1 * inc, 0.005, 0.035, 1.5, True)
    # beams taken from poses apart: every cone the window meets must be free
    assert not covered_free(f, 0.0, inc, ra, 0.005, 0.016, 1.5, False)
    assert covered_free(f, 0.0, inc, ra, 0.0, 0.003, 1.5, False)


# ---------------------------------------------------------------- beams taken from poses apart
def _cones_hold(x, y, o, th, a0, inc, ra, f, tol=1e-9):
    """The beams whose own cone (from their own sensor pose ``o[i]``, heading ``th[i]``) holds
    the point, nearer than their free range."""
    d = np.hypot(x - o[:, 0], y - o[:, 1])
    b = np.arctan2(y - o[:, 1], x - o[:, 0]) - th
    off = b - (a0 + inc * np.arange(f.size))
    off = (off + math.pi) % (2 * math.pi) - math.pi
    return (np.abs(off) <= ra + tol) & (d < f)


def _certified(x, y, box, f, a0, inc, ra, smin):
    """The map kernels' decision for a point: its bearings over the sensor box in the window of
    cones free beyond its largest distance (covered_free), and no nearer than ``smin``."""
    from ivslam_cli.slam.lidar.free_cones import covered_free
    from ivslam_cli.slam.lidar.geometry import box_bearings, box_ranges

    xl, xh, yl, yh, thl, thh = box
    dxl, dxh, dyl, dyh = x - xh, x - xl, y - yh, y - yl
    r_lo, r_hi = box_ranges(dxl, dxh, dyl, dyh)
    bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
    return (not full) and r_lo >= smin and covered_free(f, a0, inc, ra, bl - thh, bh - thl, r_hi, False)


@st.composite
def _swept_scan(draw):
    """A scan whose beams are taken one after another from poses that move at most ``δ`` and
    turn at most ``η`` from one beam to the next (often the worst: turning with the sweep,
    which spreads the cones apart, and moving across the beams)."""
    nb = draw(st.integers(20, 300))
    inc = draw(st.floats(0.003, 0.02))
    ra = inc * draw(st.sampled_from([0.5, 0.52, 0.6, 0.75, 1.0]))
    eta = inc * draw(st.sampled_from([0.0, 0.01, 0.05, 0.2, 0.5])) * draw(st.floats(0.0, 1.0))
    delta = draw(st.sampled_from([0.0, 1e-4, 1e-3, 5e-3])) * draw(st.floats(0.0, 1.0))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    worst = draw(st.booleans())
    th = np.zeros(nb)
    o = np.zeros((nb, 2))
    for i in range(1, nb):
        th[i] = th[i - 1] + (eta if worst else eta * rng.uniform(-1.0, 1.0))
        a = th[i] + inc * i + (math.pi / 2 if worst else rng.uniform(-math.pi, math.pi))
        step = delta if worst else delta * rng.random()
        o[i] = o[i - 1] + step * np.array([math.cos(a), math.sin(a)])
    f = rng.uniform(0.5, 6.0, nb) if draw(st.booleans()) else np.full(nb, 6.0)
    a0 = -0.5 * (nb - 1) * inc
    return nb, inc, ra, eta, delta, o, th, f, a0, rng


@settings(max_examples=examples(ci=400))
@given(_swept_scan())
def test_swept_cones_prove_free_only_what_some_beam_saw(case):
    """The sweep: beams taken from poses apart leave slivers between their cones that no beam
    saw. Every point the kernels' rule certifies free — its window of cones over the sensor box
    that holds every beam's pose, and no nearer than :func:`sweep_free_from` — lies in the cone
    of some beam seen from that beam's own pose, nearer than its free range."""
    from ivslam_cli.slam.lidar.free_cones import sweep_free_from

    nb, inc, ra, eta, delta, o, th, f, a0, rng = case
    smin = float(sweep_free_from(np.array([[delta, eta]]), np.array([inc]), ra, False)[0])
    box = (o[:, 0].min(), o[:, 0].max(), o[:, 1].min(), o[:, 1].max(), th.min(), th.max())
    if not math.isfinite(smin):
        assert 2 * ra - inc <= eta * (1 + 1e-9)  # the cones cannot overlap by the turn: nothing
        return
    n_cert = 0
    for _ in range(300):
        s = rng.uniform(min(max(smin, 1e-3), 6.0), 6.0) if rng.random() < 0.8 else rng.uniform(0.0, 0.2)
        b = rng.uniform(a0, a0 + (nb - 1) * inc) + rng.uniform(th.min(), th.max())
        x, y = o[:, 0].mean() + s * math.cos(b), o[:, 1].mean() + s * math.sin(b)
        if _certified(x, y, box, f, a0, inc, ra, smin):
            n_cert += 1
            assert _cones_hold(x, y, o, th, a0, inc, ra, f).any(), (x, y, smin)


@settings(max_examples=examples(ci=400))
@given(_swept_scan())
def test_swept_rectangles_certified_free_lie_in_some_beams_own_cone(case):
    """The matcher's test of a rectangle against a swept scan (:func:`_seg_free` from its sensor
    box holding every beam's pose, ``smin`` of :func:`sweep_free_from`): every point it
    certifies free lies in the cone of some beam seen from that beam's own pose, nearer than its
    free range (a scan not swept: each bearing from any cone free beyond it)."""
    from ivslam_cli.slam.lidar.free_cones import sweep_free_from

    nb, inc, ra, eta, delta, o, th, f, a0, rng = case
    smin = float(sweep_free_from(np.array([[delta, eta]]), np.array([inc]), ra, False)[0])
    cx, cy = 0.5 * (o[:, 0].min() + o[:, 0].max()), 0.5 * (o[:, 1].min() + o[:, 1].max())
    rad = float(np.max(np.hypot(o[:, 0] - cx, o[:, 1] - cy))) * (1 + 1e-9) + 1e-12
    for _ in range(300):
        s = rng.uniform(0.01, 6.0)
        b = rng.uniform(a0, a0 + (nb - 1) * inc) + rng.uniform(th.min(), th.max())
        x, y = cx + s * math.cos(b), cy + s * math.sin(b)
        phi = rng.uniform(-math.pi, math.pi)
        h = rng.choice([1e-9, 1e-3, 0.02])
        if _seg_free(x - cx, y - cy, math.cos(phi), math.sin(phi), h + rad, h + rad, th.min(), th.max(), f, a0, inc,
                     ra, smin):
            for px, py in ((x, y), (x + h * math.cos(phi), y + h * math.sin(phi)),
                           (x - h * math.sin(phi), y + h * math.cos(phi))):
                assert _cones_hold(px, py, o, th, a0, inc, ra, f, tol=1e-9).any(), (px, py, smin)


def test_a_turn_with_the_sweep_opens_slivers_no_beam_saw():
    """A test that can fail: cones that only touch (bearing bound = half the step), the sensor
    turning by ``η`` from each beam to the next in the sweep's direction. Between beams ``i`` and
    ``i+1`` a sliver of ``η`` is in neither cone, yet every pose of the box sees it within the
    window of cones: one pose for the whole scan would call it free. The sweep's rule proves
    nothing from such a scan (inf), and with cones overlapping by more than the turn, from 0."""
    from ivslam_cli.slam.lidar.free_cones import sweep_free_from

    nb, inc, eta = 100, 0.01, 0.002
    ra = 0.5 * inc
    a0 = -0.5 * (nb - 1) * inc
    th = eta * np.arange(nb)
    o = np.zeros((nb, 2))
    f = np.full(nb, 6.0)
    box = (0.0, 0.0, 0.0, 0.0, th[0], th[-1])
    i = 50
    b = a0 + i * inc + ra + th[i] + 0.5 * eta  # between cone i's upper edge and cone i+1's lower one
    x, y = 3.0 * math.cos(b), 3.0 * math.sin(b)
    assert not _cones_hold(x, y, o, th, a0, inc, ra, f, tol=0.0).any()
    assert _certified(x, y, box, f, a0, inc, ra, 0.0)  # one pose per scan: unsound
    assert sweep_free_from(np.array([[0.0, eta]]), np.array([inc]), ra, False)[0] == math.inf
    assert not _certified(x, y, box, f, a0, inc, ra, math.inf)
    assert sweep_free_from(np.array([[0.0, eta]]), np.array([inc]), 0.5 * inc + eta, False)[0] < 1e-300
    assert 0.0 < sweep_free_from(np.array([[0.0, eta]]), np.array([inc]), ra, True)[0] < 1e-300  # fill_gaps: assumed

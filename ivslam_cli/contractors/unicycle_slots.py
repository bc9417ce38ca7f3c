"""The slots of the SIMD unicycle kernel (:mod:`~ivslam_cli.contractors.ctc_unicycle_simd`):
the layout of the slot buffer, the boxes in and out, and the end of a round.

A round of a slot ends its box when it shrank no width by ``RELATIVE_STOP`` from the bounds at
the round's start (its heading step and its position part together, as
:func:`~ivslam_cli.contractors.ctc_unicycle.unicycle_scalar` measures a pass) or when
``MAX_ROUNDS`` rounds are used up. Every bound written out is one the contractors gave: nothing
here widens or narrows a box beyond taking the hull of a round's pieces.
"""

from __future__ import annotations

from numba import njit

from ivslam_cli.contractors.ctc_unicycle import MAX_PASSES as MAX_ROUNDS
from ivslam_cli.contractors.ctc_unicycle import RELATIVE_STOP
from ivslam_cli.contractors.simd_polar_lanes import CHUNK
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO
from ivslam_cli.interval.rounding import INF

E = EMPTY_LO
F = EMPTY_HI
# the 24 bounds of a box, in the order of unicycle_scalar
X0, Y0, T0, X1, Y1, T1, V, W, DT, QX, QY, QT = range(0, 24, 2)
# Slots: NB boxes in flight, each at its own round; a slot whose box is done takes the next
# box. The slot buffer B holds slot j's values at B[r * NB + j]: the 24 bounds (rows 0..23, in
# unicycle_scalar's order), the hull of the round's pieces (ACC..ACC+23), the slot's state
# and the plan of its position part. The SIMD loops over slots use B only, at compile-time row
# offsets (LLVM needs no runtime alias checks then). Rows are 1056 bytes apart, so no two of
# the first 128 rows are a multiple of 4 KiB apart: a slot's column (read and written value by
# value when a box comes in or goes out) then has no loads that alias earlier stores.
NB = 132
assert 2 * NB <= CHUNK  # the lanes of the SIMD slots of a round fit in one chunk
ACC = 24
LT0L, LT0H, LDTL, LDTH = 48, 49, 50, 51  # th0 and dt after the slot's last position part
LIVE, RND, HOK, POS, NPC = 52, 53, 54, 55, 56
PC = 57  # the pieces _plan found: piece t at PC + 5 t + (sign of s, quadrant, copy, psi lo, hi)
SL_, SH_ = 67, 68  # s = v dt
DXL, DXH, DYL, DYH = 69, 70, 71, 72  # dx = (x1 - x0) - qx, dy likewise
AXL, AXH, AYL, AYH = 73, 74, 75, 76  # x1 - x0, y1 - y0
WID0 = 77  # 12 rows: the widths (hi - lo) of the 12 variables at the start of the round
NEED = WID0 + 12  # 1 while the slot's round is to start with its heading
BROWS = NEED + 1
# B[POS]: the round's position part
KEEP, SIMD, GEN, NOTHING = 0.0, 1.0, 2.0, 3.0


@njit(cache=True, inline="always", error_model="numpy")
def _shrunk(B, j, at):
    """The largest relative width reduction over the 12 variables of slot ``j`` from the widths
    at the round's start (``WID0`` rows) to the bounds in the rows from ``at`` on (as
    ``ctc_unicycle.shrink``)."""
    N = NB
    prog = 0.0
    for k in range(0, 24, 2):
        w0 = B[(WID0 + k // 2) * N + j]
        w1 = B[(at + k + 1) * N + j] - B[(at + k) * N + j]
        s = (1.0 if w1 < INF else 0.0) if w0 == INF else ((w0 - w1) / w0 if w0 > 0.0 else 0.0)
        prog = s if s > prog else prog
    return prog


@njit(cache=True, error_model="numpy")
def _finish_kept(B):
    """After the heading step, as selects (a SIMD loop): a live slot whose position part is to
    be ``KEEP`` (:func:`_plan`'s test) and whose heading shrank no width by ``RELATIVE_STOP``
    (or whose rounds are used up) is done now, with the bounds :func:`_progress` would give it
    after the round (the box as it is); ``B[LIVE]`` is 2 there. Returns how many."""
    N = NB
    done = 0
    for j in range(N):
        keep = (B[LIVE * N + j] > 0.5) & (B[HOK * N + j] > 0.5) & (B[RND * N + j] > 0.5)
        keep = keep & (B[T0 * N + j] == B[LT0L * N + j]) & (B[(T0 + 1) * N + j] == B[LT0H * N + j])
        keep = keep & (B[DT * N + j] == B[LDTL * N + j]) & (B[(DT + 1) * N + j] == B[LDTH * N + j])
        more = (_shrunk(B, j, 0) >= RELATIVE_STOP) & (B[RND * N + j] + 1.0 < MAX_ROUNDS)
        end = keep & (not more)
        B[RND * N + j] = B[RND * N + j] + 1.0 if end else B[RND * N + j]
        B[LIVE * N + j] = 2.0 if end else B[LIVE * N + j]
        done += 1 if end else 0
    return done


@njit(cache=True, error_model="numpy")
def _progress(B):
    """End of the round of every live slot, as selects (a SIMD loop): its box becomes the hull
    of the round (empty if that is); ``B[LIVE]`` stays 1 while the round (its heading and its
    position part, from the ``WID0`` rows) shrank some width by ``RELATIVE_STOP`` and rounds
    are left, else it is 2 (done); the ``WID0`` rows take the widths of the new bounds."""
    N = NB
    for j in range(N):
        live = B[LIVE * N + j] > 0.5
        empty = not (B[ACC * N + j] <= B[(ACC + 1) * N + j])
        more = (not empty) & (_shrunk(B, j, ACC) >= RELATIVE_STOP) & (B[RND * N + j] + 1.0 < MAX_ROUNDS)
        for r in range(24):
            v = (E if r % 2 == 0 else F) if empty else B[(ACC + r) * N + j]
            B[r * N + j] = v if live else B[r * N + j]
        B[LT0L * N + j] = B[T0 * N + j] if live else B[LT0L * N + j]
        B[LT0H * N + j] = B[(T0 + 1) * N + j] if live else B[LT0H * N + j]
        B[LDTL * N + j] = B[DT * N + j] if live else B[LDTL * N + j]
        B[LDTH * N + j] = B[(DT + 1) * N + j] if live else B[LDTH * N + j]
        B[RND * N + j] = B[RND * N + j] + 1.0 if live else B[RND * N + j]
        B[LIVE * N + j] = (1.0 if more else 2.0) if live else B[LIVE * N + j]
        for k in range(12):  # the next round starts from this box
            w = B[(2 * k + 1) * N + j] - B[2 * k * N + j]
            B[(WID0 + k) * N + j] = w if live else B[(WID0 + k) * N + j]


@njit(cache=True, inline="always")
def _load(arrs, B, j, i, n, ok):
    """Take boxes from row ``i`` on into slot ``j`` (its bounds and their widths, ``WID0``):
    rows with an empty variable are emptied on the way; returns the next row (``n`` if none is
    left: the slot is then free). The twelve arrays are named one by one: an index into the
    tuple that varies at run time costs a copy of the tuple per access."""
    N = NB
    a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11 = arrs
    while i < n:
        good = (a0[2 * i] <= a0[2 * i + 1] and a1[2 * i] <= a1[2 * i + 1]
                and a2[2 * i] <= a2[2 * i + 1] and a3[2 * i] <= a3[2 * i + 1]
                and a4[2 * i] <= a4[2 * i + 1] and a5[2 * i] <= a5[2 * i + 1]
                and a6[2 * i] <= a6[2 * i + 1] and a7[2 * i] <= a7[2 * i + 1]
                and a8[2 * i] <= a8[2 * i + 1] and a9[2 * i] <= a9[2 * i + 1]
                and a10[2 * i] <= a10[2 * i + 1] and a11[2 * i] <= a11[2 * i + 1])
        if good:
            B[0 * N + j], B[1 * N + j] = a0[2 * i], a0[2 * i + 1]
            B[2 * N + j], B[3 * N + j] = a1[2 * i], a1[2 * i + 1]
            B[4 * N + j], B[5 * N + j] = a2[2 * i], a2[2 * i + 1]
            B[6 * N + j], B[7 * N + j] = a3[2 * i], a3[2 * i + 1]
            B[8 * N + j], B[9 * N + j] = a4[2 * i], a4[2 * i + 1]
            B[10 * N + j], B[11 * N + j] = a5[2 * i], a5[2 * i + 1]
            B[12 * N + j], B[13 * N + j] = a6[2 * i], a6[2 * i + 1]
            B[14 * N + j], B[15 * N + j] = a7[2 * i], a7[2 * i + 1]
            B[16 * N + j], B[17 * N + j] = a8[2 * i], a8[2 * i + 1]
            B[18 * N + j], B[19 * N + j] = a9[2 * i], a9[2 * i + 1]
            B[20 * N + j], B[21 * N + j] = a10[2 * i], a10[2 * i + 1]
            B[22 * N + j], B[23 * N + j] = a11[2 * i], a11[2 * i + 1]
            for k in range(12):
                B[(WID0 + k) * N + j] = B[(2 * k + 1) * N + j] - B[2 * k * N + j]
            B[LIVE * N + j] = 1.0
            B[RND * N + j] = 0.0
            return i + 1
        a0[2 * i], a0[2 * i + 1] = E, F
        a1[2 * i], a1[2 * i + 1] = E, F
        a2[2 * i], a2[2 * i + 1] = E, F
        a3[2 * i], a3[2 * i + 1] = E, F
        a4[2 * i], a4[2 * i + 1] = E, F
        a5[2 * i], a5[2 * i + 1] = E, F
        a6[2 * i], a6[2 * i + 1] = E, F
        a7[2 * i], a7[2 * i + 1] = E, F
        a8[2 * i], a8[2 * i + 1] = E, F
        a9[2 * i], a9[2 * i + 1] = E, F
        a10[2 * i], a10[2 * i + 1] = E, F
        a11[2 * i], a11[2 * i + 1] = E, F
        ok[i] = False
        i += 1
    B[LIVE * N + j] = 0.0
    return i


@njit(cache=True, inline="always")
def _store(arrs, B, j, i):
    """Slot ``j``'s box into row ``i`` of the twelve arrays."""
    N = NB
    a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11 = arrs
    a0[2 * i], a0[2 * i + 1] = B[0 * N + j], B[1 * N + j]
    a1[2 * i], a1[2 * i + 1] = B[2 * N + j], B[3 * N + j]
    a2[2 * i], a2[2 * i + 1] = B[4 * N + j], B[5 * N + j]
    a3[2 * i], a3[2 * i + 1] = B[6 * N + j], B[7 * N + j]
    a4[2 * i], a4[2 * i + 1] = B[8 * N + j], B[9 * N + j]
    a5[2 * i], a5[2 * i + 1] = B[10 * N + j], B[11 * N + j]
    a6[2 * i], a6[2 * i + 1] = B[12 * N + j], B[13 * N + j]
    a7[2 * i], a7[2 * i + 1] = B[14 * N + j], B[15 * N + j]
    a8[2 * i], a8[2 * i + 1] = B[16 * N + j], B[17 * N + j]
    a9[2 * i], a9[2 * i + 1] = B[18 * N + j], B[19 * N + j]
    a10[2 * i], a10[2 * i + 1] = B[20 * N + j], B[21 * N + j]
    a11[2 * i], a11[2 * i + 1] = B[22 * N + j], B[23 * N + j]


@njit(cache=True, inline="always")
def _swap(arrs, B, boxid, ok, nxt, n):
    """Every done slot writes its box out and takes the next one (``B[NEED]`` 1 there);
    returns the next row to take."""
    N = NB
    for j in range(N):
        if B[LIVE * N + j] < 1.5:
            continue
        i = boxid[j]
        _store(arrs, B, j, i)
        ok[i] = B[X0 * N + j] <= B[(X0 + 1) * N + j]
        nxt = _load(arrs, B, j, nxt, n, ok)
        boxid[j] = nxt - 1 if B[LIVE * N + j] > 0.5 else -1
        B[NEED * N + j] = B[LIVE * N + j]
    return nxt

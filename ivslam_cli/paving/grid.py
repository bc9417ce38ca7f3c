"""The regular grid and the subpaving stored on it (:class:`GridPaving`).

A grid is an origin ``(ox, oy)`` and a resolution ``eps``. Cell ``(i, j)`` is the box
``[x(i), x(i+1)] x [y(j), y(j+1)]`` with ``x(i) = ox + i * eps`` evaluated in float64, always with
that same expression, so neighbouring cells share their float boundary exactly: the cells tile
the plane with no gap whatever the rounding (``x(i)`` is non-decreasing in ``i``).

A :class:`GridPaving` keeps the cells that are not proven outside its set, as a structure of
arrays sorted by a 64-bit key of ``(i, j)``:

- ``label`` INNER (the whole cell is proven inside the set) or BOUNDARY (the cell may hold points
  of the set);
- ``parts`` / ``start``: the boxes of cell ``k`` are ``parts[start[k]:start[k + 1]]`` (at least
  one, each inside the cell); together they hold every point of the set lying in the cell. An
  INNER cell has one part, the cell itself; a BOUNDARY cell may have several (e.g. the
  contracted pieces of the cell bisected into a sub-grid by ``pave(..., sub=s)``);
- ``box``: the hull of the cell's parts, the one-box-per-cell view.

Outer approximation = union of the parts (also: of the boxes, a looser one); inner
approximation = union of the INNER cells. Pavings on the same grid (same origin and
resolution) combine cell by cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

INNER = 1  # same codes as ivslam_cli.results.model LABEL_INNER / LABEL_BOUNDARY
BOUNDARY = 2

_BIAS = 1 << 30  # (i + _BIAS) < 2^31, so the key stays a positive int64
MAX_INDEX = (1 << 30) - 1  # |i|, |j| must stay below this to fit the 64-bit key


class PavingLimitError(ValueError):
    """A paving would exceed its cell limit (raise the limit or coarsen ``eps``)."""


@njit(cache=True)
def cell_key(i, j):
    """64-bit key of cell ``(i, j)``; keys sort as ``(i, j)`` lexicographically."""
    return ((i + _BIAS) << 32) | (j + _BIAS)


@njit(cache=True)
def key_i(k):
    return (k >> 32) - _BIAS


@njit(cache=True)
def key_j(k):
    return (k & 0xFFFFFFFF) - _BIAS


@njit(cache=True)
def coord(o, i, eps):
    """Float boundary ``o + i * eps`` of the grid (the one expression used everywhere)."""
    return o + float(i) * eps


@njit(cache=True)
def cell_of(o, eps, x):
    """Index range ``(i_lo, i_hi)`` of the cells whose closed float interval holds ``x``.

    Usually one cell, two when ``x`` is on a boundary. The division only gives a guess; the
    answer is checked against :func:`coord` so rounding cannot place ``x`` in the wrong cell.
    """
    g = math.floor((x - o) / eps)
    i = np.int64(g)
    while coord(o, i, eps) > x:
        i -= 1
    while coord(o, i + 1, eps) < x:
        i += 1
    lo = i - 1 if coord(o, i, eps) == x else i  # x on the left edge: cell i-1 holds it too
    hi = i + 1 if coord(o, i + 1, eps) == x else i  # on the right edge: cell i+1 too
    return lo, hi


@dataclass(frozen=True)
class Grid:
    """A regular grid: origin ``(ox, oy)`` and resolution ``eps > 0`` (both exact doubles)."""

    ox: float
    oy: float
    eps: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.ox) and math.isfinite(self.oy)):
            raise ValueError(f"grid origin must be finite, got ({self.ox}, {self.oy})")
        if not (math.isfinite(self.eps) and self.eps > 0.0):
            raise ValueError(f"grid resolution eps must be finite and > 0, got {self.eps}")

    def cell_range(self, lo: float, hi: float, axis: int) -> tuple[int, int]:
        """Inclusive cell indices ``(a, b)`` whose cells cover ``[lo, hi]`` on ``axis`` (snapped outward)."""
        o = self.ox if axis == 0 else self.oy
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValueError(f"domain bounds must be finite with lo <= hi, got [{lo}, {hi}]")
        if max(abs(lo - o), abs(hi - o)) / self.eps >= MAX_INDEX - 2:
            raise PavingLimitError(f"[{lo}, {hi}] is too far from the grid origin at eps={self.eps}")
        a = cell_of(o, self.eps, lo)[1]  # on an edge: the cell to the right of it
        b = max(a, cell_of(o, self.eps, hi)[0])  # on an edge: the cell to the left of it
        if max(abs(a), abs(b)) >= MAX_INDEX:
            raise PavingLimitError(f"[{lo}, {hi}] is too far from the grid origin at eps={self.eps}")
        return int(a), int(b)


@dataclass(frozen=True, eq=False)
class GridPaving:
    """Cells of ``grid`` that may hold points of a set, with their labels and boxes.

    ``key`` (N,) int64 strictly increasing (see :func:`cell_key`); ``label`` (N,) uint8 in
    {INNER, BOUNDARY}; ``box`` (N, 2, 2) float64, ``box[k, d] = [lo, hi]`` on axis d (x, y),
    a non-empty box inside cell ``k`` (the cell itself when INNER), the hull of its parts;
    ``parts`` (B, 2, 2) float64 and ``start`` (N + 1,) int64 non-decreasing with
    ``start[0] = 0``, ``start[N] = B`` and at least one part per cell: cell ``k``'s parts are
    ``parts[start[k]:start[k + 1]]``, non-empty boxes inside ``box[k]`` (just the cell when
    INNER). Without ``parts``/``start`` every cell has the one part ``box[k]``.
    ``inner_parts`` (K, 2, 2) float64: boxes proven inside the set within BOUNDARY cells, each
    inside one of its cell's parts, interiors pairwise disjoint (default: none). The inner
    approximation is the INNER cells and the inner parts; operations that build a new paving
    keep only INNER cells (a smaller inner approximation, still sound).
    """

    grid: Grid
    key: np.ndarray
    label: np.ndarray
    box: np.ndarray
    parts: np.ndarray = None  # type: ignore[assignment]  # (B, 2, 2); default: box
    start: np.ndarray = None  # type: ignore[assignment]  # (N + 1,); default: 0..N
    inner_parts: np.ndarray = None  # type: ignore[assignment]  # (K, 2, 2); default: none

    def __post_init__(self) -> None:
        n = self.key.shape[0]
        if (self.parts is None) != (self.start is None):
            raise ValueError("GridPaving: give both parts and start, or neither")
        if self.inner_parts is None:
            object.__setattr__(self, "inner_parts", np.empty((0, 2, 2)))
        if self.parts is None:
            object.__setattr__(self, "parts", self.box)
            object.__setattr__(self, "start", np.arange(n + 1, dtype=np.int64))
        if self.start.shape != (n + 1,) or self.start[-1] != self.parts.shape[0]:
            raise ValueError(f"GridPaving: start must be (N + 1,) ending at the number of parts, "
                             f"got {self.start.shape} for N={n}, B={self.parts.shape[0]}")

    def __len__(self) -> int:
        return int(self.key.shape[0])

    @property
    def n_parts(self) -> np.ndarray:
        """(N,) number of parts of each cell (>= 1)."""
        return np.diff(self.start)

    @property
    def part_cell(self) -> np.ndarray:
        """(B,) index of the cell each part belongs to."""
        return np.repeat(np.arange(len(self), dtype=np.int64), self.n_parts)

    @property
    def i(self) -> np.ndarray:
        return (self.key >> 32) - _BIAS

    @property
    def j(self) -> np.ndarray:
        return (self.key & 0xFFFFFFFF) - _BIAS

    @property
    def inner_mask(self) -> np.ndarray:
        return self.label == INNER

    def cells(self) -> np.ndarray:
        """The (N, 2, 2) cell boxes of the stored cells."""
        g = self.grid
        i = self.i.astype(np.float64)
        j = self.j.astype(np.float64)
        out = np.empty((len(self), 2, 2))
        out[:, 0, 0] = g.ox + i * g.eps
        out[:, 0, 1] = g.ox + (i + 1.0) * g.eps
        out[:, 1, 0] = g.oy + j * g.eps
        out[:, 1, 1] = g.oy + (j + 1.0) * g.eps
        return out

    # ----------------------------------------------------------------- measures
    def is_empty(self) -> bool:
        """True when the outer approximation is empty (then the set is proven empty)."""
        return len(self) == 0

    def outer_area(self) -> float:
        """Area of the outer approximation, rounded up: >= the area of the set ∩ domain.

        Per cell, the smaller of the sum of its parts' areas and its box's area (parts may
        overlap after a union), so it is never above :meth:`box_area`.
        """
        if len(self) == 0:
            return 0.0
        a = np.minimum(_cell_parts_area(self.parts, self.start), _box_areas(self.box, np.inf))
        return float(np.nextafter(math.fsum(a), np.inf))

    def box_area(self) -> float:
        """Area of the one-box-per-cell outer approximation (the union of ``box``), rounded up."""
        return _area(self.box, up=True)

    def inner_area(self) -> float:
        """Area of the inner approximation (INNER cells and inner parts), rounded down: <= the
        area of the set."""
        a = _area(self.box[self.inner_mask], up=False)
        if self.inner_parts.shape[0] == 0:
            return a
        b = _area(self.inner_parts, up=False)
        return float(np.nextafter(a + b, -np.inf))

    def hull(self) -> np.ndarray:
        """Bounding box (2, 2) of the outer approximation: an outer approximation of the set's
        hull. Empty paving: ``[[inf, -inf], [inf, -inf]]``."""
        out = np.empty((2, 2))
        if len(self) == 0:
            out[:, 0] = np.inf
            out[:, 1] = -np.inf
            return out
        out[:, 0] = self.box[:, :, 0].min(axis=0)
        out[:, 1] = self.box[:, :, 1].max(axis=0)
        return out

    def to_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """``(boxes (B, 2, 2) float64, label (B,) uint8)``, 1 inner / 2 boundary (HDF5 layout):
        the parts, each with its cell's label.

        The union of the boxes is the outer approximation; the label-1 boxes form the inner one.
        """
        return self.parts.copy(), self.label[self.part_cell]

    def same_grid(self, other: GridPaving) -> None:
        if self.grid != other.grid:
            raise ValueError(f"pavings are on different grids: {self.grid} vs {other.grid}")

    def __repr__(self) -> str:
        n_in = int(np.count_nonzero(self.inner_mask))
        return (f"GridPaving(eps={self.grid.eps}, origin=({self.grid.ox}, {self.grid.oy}), "
                f"{n_in} inner + {len(self) - n_in} boundary cells, {self.parts.shape[0]} boxes)")


def _box_areas(box: np.ndarray, to: float) -> np.ndarray:
    """Area of each box, rounded towards ``to`` (one ulp per operation)."""
    w = np.nextafter(box[:, 0, 1] - box[:, 0, 0], to)
    v = np.nextafter(box[:, 1, 1] - box[:, 1, 0], to)
    return np.nextafter(w * v, to)


def _area(box: np.ndarray, up: bool) -> float:
    """Sum of box areas with directed rounding (one ulp per operation, correctly rounded sum)."""
    if box.shape[0] == 0:
        return 0.0
    to = np.inf if up else -np.inf
    return float(np.nextafter(math.fsum(_box_areas(box, to)), to))


@njit(cache=True)
def _cell_parts_area(parts, start):
    """Per cell, the sum of its parts' areas rounded up (a single part of non-zero area: as
    :func:`_box_areas`; degenerate parts add exactly 0)."""
    n = start.shape[0] - 1
    out = np.empty(n)
    for k in range(n):
        s = 0.0
        for q in range(start[k], start[k + 1]):
            if parts[q, 0, 1] == parts[q, 0, 0] or parts[q, 1, 1] == parts[q, 1, 0]:
                continue  # a segment or a point: area exactly 0
            w = np.nextafter(parts[q, 0, 1] - parts[q, 0, 0], np.inf)
            v = np.nextafter(parts[q, 1, 1] - parts[q, 1, 0], np.inf)
            a = np.nextafter(w * v, np.inf)
            s = a if s == 0.0 else np.nextafter(s + a, np.inf)
        out[k] = s
    return out


@njit(cache=True)
def prune_contained(parts, lo, hi, keep, disjoint=False):
    """``keep[q]`` for ``q`` in ``lo..hi``: False when another part of the pool contains part
    ``q`` (of equal parts, the first is kept). The union of the kept parts is the pool's.
    ``disjoint``: the parts' interiors are known disjoint, so only segments and points are
    searched (a part with an interior lies in no other)."""
    for q in range(lo, hi):
        keep[q] = True
        if disjoint and parts[q, 0, 0] < parts[q, 0, 1] and parts[q, 1, 0] < parts[q, 1, 1]:
            continue
        for r in range(lo, hi):
            if r == q:
                continue
            if (parts[r, 0, 0] <= parts[q, 0, 0] and parts[q, 0, 1] <= parts[r, 0, 1]
                    and parts[r, 1, 0] <= parts[q, 1, 0] and parts[q, 1, 1] <= parts[r, 1, 1]):
                equal = (parts[r, 0, 0] == parts[q, 0, 0] and parts[q, 0, 1] == parts[r, 0, 1]
                         and parts[r, 1, 0] == parts[q, 1, 0] and parts[q, 1, 1] == parts[r, 1, 1])
                if not equal or r < q:
                    keep[q] = False
                    break


def empty_paving(grid: Grid) -> GridPaving:
    return GridPaving(grid, np.empty(0, np.int64), np.empty(0, np.uint8), np.empty((0, 2, 2)))

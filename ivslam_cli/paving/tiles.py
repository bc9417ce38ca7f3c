"""A grid map of ε-cells stored in fixed-size tiles allocated as the map grows.

The plane is cut into cells ``[i ε, (i + 1) ε] x [j ε, (j + 1) ε]`` (integers ``i, j`` of
any sign, ``ε`` the double given; the real products ``i ε`` define the cells, kernels enclose
them outward). Cells are grouped in tiles of ``TILE x TILE`` (64 x 64); a tile exists once a
cell of it was written, so memory follows the explored area and any extent works.

Each cell holds one ``uint8`` of flags (bits can be combined):

- ``EMPTY`` (1): the cell is proven free of obstacles (∪ P_EMPTY^k).
- ``OBST_NEW`` (2): the cell may hold the endpoint of a *new* beam (∪ P_OBSTACLE^k).
- ``OBST_OLD`` (4): the cell may hold the endpoint of an *old* beam (∪ P_OLD^k).

and the map state is derived from them (:func:`state_of`): ``EMPTY_STATE`` if proven free,
``OBSTACLE`` if in (∪ P_OBSTACLE^k) ∩ (∪ P_OLD^k) and not proven free, else ``UNKNOWN``.
A cell with any flag is *measured*.

The tile index is an open-addressing hash table in numpy arrays (keys ``int64`` packing the
tile coordinates, linear probing, grown at half load): no Python dict, usable from numba.
Everything that touches cells is an ``@njit`` kernel; :class:`TileMap` is the Python handle
that owns the arrays and replaces them when a kernel grew them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import down, up

TILE_SHIFT = 6
TILE = 1 << TILE_SHIFT  # cells per tile side
TILE_MASK = TILE - 1

EMPTY = np.uint8(1)
OBST_NEW = np.uint8(2)
OBST_OLD = np.uint8(4)

UNKNOWN = 0
EMPTY_STATE = 1
OBSTACLE = 2

_NO_KEY = np.int64(-(2**63))
_HASH_MUL = np.uint64(0x9E3779B97F4A7C15)


# ---------------------------------------------------------------- the tile index (numba)
@njit(cache=True)
def pack(tx: int, ty: int) -> np.int64:
    """One int64 key for tile ``(tx, ty)`` (each in the int32 range)."""
    return np.int64(((np.int64(tx) + 2**31) << 32) | (np.int64(ty) + 2**31))


@njit(cache=True)
def _slot(key: np.int64, mask: int) -> int:
    h = np.uint64(key) * _HASH_MUL
    return int(h >> np.uint64(32)) & mask


@njit(cache=True)
def find(keys: np.ndarray, slots: np.ndarray, tx: int, ty: int) -> int:
    """Index of tile ``(tx, ty)`` in the tile array, or -1 if it was never allocated (also
    outside the index's int32 coordinates: such a tile is unknown, it cannot be allocated)."""
    if not (-(2**31) <= tx < 2**31 and -(2**31) <= ty < 2**31):
        return -1
    key = pack(tx, ty)
    mask = keys.shape[0] - 1
    s = _slot(key, mask)
    while True:
        k = keys[s]
        if k == key:
            return slots[s]
        if k == _NO_KEY:
            return -1
        s = (s + 1) & mask


@njit(cache=True)
def _insert_key(keys, slots, key, index):
    mask = keys.shape[0] - 1
    s = _slot(key, mask)
    while keys[s] != _NO_KEY:
        s = (s + 1) & mask
    keys[s] = key
    slots[s] = index


@njit(cache=True)
def add_tile(keys, slots, cells, coords, n, tx, ty):
    """Index of tile ``(tx, ty)``, allocating it (all-unknown) if new.

    Returns ``(index, keys, slots, cells, coords, n)``: the arrays are new ones when they
    had to grow (tables kept at most half full, tile storage doubled).
    """
    i = find(keys, slots, tx, ty)
    if i >= 0:
        return i, keys, slots, cells, coords, n
    if not (-(2**31) <= tx < 2**31 and -(2**31) <= ty < 2**31):
        raise ValueError("tile coordinates beyond the int32 range of the tile index")
    if n >= cells.shape[0]:
        cap = 2 * cells.shape[0]
        nc = np.zeros((cap, TILE, TILE), dtype=np.uint8)
        nc[:n] = cells[:n]
        nco = np.zeros((cap, 2), dtype=np.int64)
        nco[:n] = coords[:n]
        cells, coords = nc, nco
    if 2 * (n + 1) > keys.shape[0]:
        cap = 2 * keys.shape[0]
        keys = np.full(cap, _NO_KEY, dtype=np.int64)
        slots = np.full(cap, -1, dtype=np.int64)
        for t in range(n):
            _insert_key(keys, slots, pack(coords[t, 0], coords[t, 1]), t)
    _insert_key(keys, slots, pack(tx, ty), n)
    coords[n, 0] = tx
    coords[n, 1] = ty
    return n, keys, slots, cells, coords, n + 1


@njit(cache=True)
def cell_flags(keys, slots, cells, ix: int, iy: int) -> np.uint8:
    """Flags of cell ``(ix, iy)`` (0 if its tile does not exist)."""
    t = find(keys, slots, ix >> TILE_SHIFT, iy >> TILE_SHIFT)
    if t < 0:
        return np.uint8(0)
    return cells[t, ix & TILE_MASK, iy & TILE_MASK]


@njit(cache=True)
def _set_cells(keys, slots, cells, coords, n, ix, iy, flags):
    """OR ``flags[k]`` into cell ``(ix[k], iy[k])`` for every k (allocating tiles)."""
    for k in range(ix.shape[0]):
        t, keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n,
                                                    ix[k] >> TILE_SHIFT, iy[k] >> TILE_SHIFT)
        cells[t, ix[k] & TILE_MASK, iy[k] & TILE_MASK] |= flags[k]
    return keys, slots, cells, coords, n


@njit(cache=True)
def _get_cells(keys, slots, cells, ix, iy):
    out = np.zeros(ix.shape[0], dtype=np.uint8)
    for k in range(ix.shape[0]):
        out[k] = cell_flags(keys, slots, cells, ix[k], iy[k])
    return out


@njit(cache=True)
def state_of(f: np.uint8) -> np.uint8:
    """Map state of a cell from its flags (see the module docstring)."""
    if f & EMPTY:
        return np.uint8(EMPTY_STATE)
    if (f & OBST_NEW) and (f & OBST_OLD):
        return np.uint8(OBSTACLE)
    return np.uint8(UNKNOWN)


@njit(cache=True)
def _combine(ka, sa, ca, coa, na, kb, sb, cb, cob, nb, op, keys, slots, cells, coords, n):
    """Tiles of ``a op b`` (op 0: OR over the union of tiles, 1: AND over common tiles)."""
    for t in range(na):
        tx, ty = coa[t, 0], coa[t, 1]
        u = find(kb, sb, tx, ty)
        if op == 1 and u < 0:
            continue
        i, keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n, tx, ty)
        if u < 0:
            cells[i] = ca[t]
        elif op == 0:
            cells[i] = ca[t] | cb[u]
        else:
            cells[i] = ca[t] & cb[u]
    if op == 0:
        for t in range(nb):
            tx, ty = cob[t, 0], cob[t, 1]
            if find(ka, sa, tx, ty) >= 0:
                continue
            i, keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n, tx, ty)
            cells[i] = cb[t]
    return keys, slots, cells, coords, n


@njit(cache=True)
def _count_states(cells, n):
    out = np.zeros(3, dtype=np.int64)
    for t in range(n):
        for a in range(TILE):
            for b in range(TILE):
                out[state_of(cells[t, a, b])] += 1
    return out


@njit(cache=True)
def _dense(cells, coords, n, tx0, ty0, nx, ny, raw):
    out = np.zeros((nx * TILE, ny * TILE), dtype=np.uint8)
    for t in range(n):
        ox = (coords[t, 0] - tx0) * TILE
        oy = (coords[t, 1] - ty0) * TILE
        for a in range(TILE):
            for b in range(TILE):
                f = cells[t, a, b]
                out[ox + a, oy + b] = f if raw else state_of(f)
    return out


# ---------------------------------------------------------------- Python handle
@dataclass
class Dense:
    """A dense copy of a map over the bounding box of its tiles.

    ``data[a, b]`` is cell ``(i0 + a, j0 + b)`` (x index first), i.e. the square
    ``[(i0 + a) ε, (i0 + a + 1) ε] x [(j0 + b) ε, (j0 + b + 1) ε]``; ``origin = (i0 ε, j0 ε)``.
    """

    data: np.ndarray
    i0: int
    j0: int
    eps: float

    @property
    def origin(self) -> tuple[float, float]:
        return self.i0 * self.eps, self.j0 * self.eps


class TileMap:
    """A map of ε-cells in tiles (see the module docstring).

    ``eps`` is the cell side [m]. Tiles are allocated on first write; ``n_tiles`` and
    ``nbytes`` follow the explored area.
    """

    def __init__(self, eps: float, capacity: int = 16) -> None:
        if not (eps > 0.0 and np.isfinite(eps)):
            raise ValueError(f"cell size must be finite and > 0, got {eps}")
        cap = max(1, int(capacity))
        table = 1 << (2 * cap - 1).bit_length()  # a power of two >= 2 cap (probing masks)
        self.eps = float(eps)
        self.keys = np.full(table, _NO_KEY, dtype=np.int64)
        self.slots = np.full(table, -1, dtype=np.int64)
        self.cells = np.zeros((cap, TILE, TILE), dtype=np.uint8)
        self.coords = np.zeros((cap, 2), dtype=np.int64)
        self.n = 0

    # arrays as one tuple for kernels, and back
    def arrays(self):
        return self.keys, self.slots, self.cells, self.coords, self.n

    def set_arrays(self, keys, slots, cells, coords, n) -> None:
        self.keys, self.slots, self.cells, self.coords, self.n = keys, slots, cells, coords, int(n)

    @property
    def n_tiles(self) -> int:
        return self.n

    @property
    def nbytes(self) -> int:
        return int(self.keys.nbytes + self.slots.nbytes + self.cells.nbytes + self.coords.nbytes)

    def tile_coords(self) -> np.ndarray:
        return self.coords[: self.n].copy()

    def set(self, ix, iy, flags) -> None:
        """OR ``flags`` into cells ``(ix, iy)`` (arrays or scalars, broadcast)."""
        ix, iy, flags = (np.array(a).ravel() for a in np.broadcast_arrays(  # copies: broadcast views are read-only
            np.asarray(ix, np.int64), np.asarray(iy, np.int64), np.asarray(flags, np.uint8)))
        self.set_arrays(*_set_cells(self.keys, self.slots, self.cells, self.coords, self.n, ix, iy, flags))

    def get(self, ix, iy) -> np.ndarray:
        """Flags of cells ``(ix, iy)`` (0 where never written)."""
        ix, iy = np.broadcast_arrays(np.asarray(ix, np.int64), np.asarray(iy, np.int64))
        shape = ix.shape
        return _get_cells(self.keys, self.slots, self.cells, np.ascontiguousarray(ix).ravel(),
                          np.ascontiguousarray(iy).ravel()).reshape(shape)

    def _combine(self, other: TileMap, op: int) -> TileMap:
        if other.eps != self.eps:
            raise ValueError(f"cell sizes differ: {self.eps} and {other.eps}")
        out = TileMap(self.eps, capacity=max(1, self.n + (other.n if op == 0 else 0)))
        out.set_arrays(*_combine(*self.arrays(), *other.arrays(), op, *out.arrays()))
        return out

    def union(self, other: TileMap) -> TileMap:
        """Cell-wise OR of the flags (tiles of either map)."""
        return self._combine(other, 0)

    def intersection(self, other: TileMap) -> TileMap:
        """Cell-wise AND of the flags (tiles of both maps)."""
        return self._combine(other, 1)

    def counts(self) -> dict[str, int]:
        """Number of cells per state (``unknown`` counts only cells of allocated tiles)."""
        c = _count_states(self.cells, self.n)
        return {"unknown": int(c[UNKNOWN]), "empty": int(c[EMPTY_STATE]), "obstacle": int(c[OBSTACLE])}

    def area(self, state: str, upward: bool = True) -> float:
        """Area [m²] of the cells in ``state``, rounded up (``upward``) or down.

        A cell's area is ``ε²`` in real arithmetic; the float result encloses ``count ε²``
        from the side asked for (outer sets up, inner sets down).
        """
        k = float(self.counts()[state])
        if k == 0.0:
            return 0.0  # exactly (rounding 0 up would report a subnormal area)
        a = k * self.eps * self.eps
        return float(up(up(a)) if upward else max(0.0, down(down(a))))

    def dense(self, raw: bool = False) -> Dense:
        """Dense copy over the tiles' bounding box: states (or raw flags with ``raw``)."""
        if self.n == 0:
            return Dense(np.zeros((0, 0), np.uint8), 0, 0, self.eps)
        co = self.coords[: self.n]
        tx0, ty0 = int(co[:, 0].min()), int(co[:, 1].min())
        nx, ny = int(co[:, 0].max()) - tx0 + 1, int(co[:, 1].max()) - ty0 + 1
        data = _dense(self.cells, self.coords, self.n, tx0, ty0, nx, ny, raw)
        return Dense(data, tx0 * TILE, ty0 * TILE, self.eps)

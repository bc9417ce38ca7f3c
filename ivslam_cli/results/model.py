"""The in-memory result every pipeline fills and ``ivslam report`` reads.

Conventions (the same on disk, see ``SCHEMA.md``):

- A *box* is a float64 array ``[..., 2]`` of closed intervals, ``[..., 0]`` = lo and
  ``[..., 1]`` = hi. A box is **empty** when any of its intervals has ``not lo <= hi``
  (the kernels write empty as ``lo = +inf, hi = -inf``); infinite bounds are allowed.
- Ragged data are flat arrays plus ``offsets`` of length ``n + 1``: the boxes of pair ``p``
  are ``boxes[offsets[p]:offsets[p+1]]``.
- Text columns (constraint kinds, reasons) are numpy unicode arrays in memory; the HDF5
  writer stores them as integer codes plus a vocabulary so no variable-length data is big.

Every enclosure here is an *outer* approximation of the true quantity (if the stated bounds
hold, possibly relaxed by q as ``Consistency.assumption`` says), except the ``inner`` boxes
of a pair subpaving (proven to be inside the set) and ``MapGrid`` cells in state ``EMPTY``
(proven free); ``LogOddsGrid`` is no enclosure at all (a probabilistic baseline). Nothing in this module computes; it only holds and checks shapes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ivslam_cli.logs.model import Dropped, GroundTruth

MODES = ("pairs", "landmarks", "lidar")

# Pair-subpaving box labels. The outer approximation is inner ∪ boundary.
LABEL_INNER = 1
LABEL_BOUNDARY = 2

# Map-grid cell states.
CELL_UNKNOWN = 0
CELL_EMPTY = 1
CELL_OBSTACLE = 2

# Width-history kinds (keys of ``Consistency.widths``).
WIDTH_KINDS = ("pair", "landmark", "pose")


def _str_array(values: Any = ()) -> np.ndarray:
    """A 1-D numpy unicode array (``<U1`` when empty)."""
    arr = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=str)
    return arr.reshape(-1) if arr.size else np.zeros(0, dtype="<U1")


def box_is_empty(box: np.ndarray) -> np.ndarray:
    """Boolean mask over the leading axes: True where some interval has ``not lo <= hi``."""
    box = np.asarray(box, dtype=np.float64)
    return ~np.all(box[..., 0] <= box[..., 1], axis=-1)


@dataclass
class ResultProvenance:
    """Where a result comes from: enough to rerun it.

    ``config`` is the resolved configuration (every bound actually used, see
    ``ivslam_cli.config``); ``input_sha256`` is of the file, or for a directory (bag
    directories, MRCLAM) of its files as computed by ``results.checksum.input_sha256``.
    """

    ivslam_version: str
    command: str
    config: dict[str, Any]
    input_path: str
    input_sha256: str
    input_format: str
    topics: dict[str, str] = field(default_factory=dict)
    dropped: list[Dropped] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass
class Poses:
    """Pose enclosures: ``box[k]`` holds (x, y, θ) of the robot at ``stamp[k]``.

    θ is an interval on the real line (it may extend beyond ±π); the true heading modulo 2π
    is in it. Nothing is claimed between two stamps; ``report`` checks each box against the
    truth at its own stamp (see ``report.core``).

    ``frame``: :data:`FRAME_WORLD` (the boxes hold the pose in the log's world frame: an
    initial pose was given or taken from the truth) or :data:`FRAME_FIRST_POSE` (the map frame
    is the robot pose at ``origin_stamp``: the boxes hold the pose relative to it).

    LiDAR submap runs add, per pose row, its home submap (``submap``, −1: none) and its box in
    that submap's frame (``relative``: the robot pose relative to the submap's anchor pose).
    """

    stamp: np.ndarray  # (N,) float64, non-decreasing
    box: np.ndarray  # (N, 3, 2) float64
    frame: str = "world"
    origin_stamp: float = float("nan")
    submap: np.ndarray | None = None  # (N,) int64
    relative: np.ndarray | None = None  # (N, 3, 2) float64

    def __len__(self) -> int:
        return int(self.stamp.shape[0])


FRAME_WORLD = "world"
FRAME_FIRST_POSE = "first pose"
FRAMES = (FRAME_WORLD, FRAME_FIRST_POSE)

@dataclass
class PoseSets:
    """Pose sets (landmarks mode): the enclosure of the pose at row ``k`` of ``Result.poses`` is
    the union of ``boxes[offsets[k]:offsets[k+1]]`` (each ``(x, y, θ)``, θ on the real line as
    in ``Poses``); ``Poses.box[k]`` is its hull. A set with no box is empty."""

    offsets: np.ndarray  # (N+1,) int64
    boxes: np.ndarray  # (B, 3, 2) float64

    def __len__(self) -> int:
        return int(self.offsets.shape[0] - 1)

    def node_boxes(self, k: int) -> np.ndarray:
        return self.boxes[self.offsets[k] : self.offsets[k + 1]]


@dataclass
class Robots:
    """A result of several robots (landmarks mode, ``--robot all``): robot ``id[r]``'s poses
    are rows ``pose_offsets[r]:pose_offsets[r+1]`` of ``Result.poses`` (stamps non-decreasing
    within each robot), its ground truth rows ``truth_offsets[r]:truth_offsets[r+1]`` of
    ``Result.truth.pose`` (all zero when there is none). The landmarks are shared."""

    id: np.ndarray  # (R,) int64
    pose_offsets: np.ndarray  # (R+1,) int64
    truth_offsets: np.ndarray  # (R+1,) int64

    def __len__(self) -> int:
        return int(self.id.shape[0])


RELATIVE_DEFINITION = (
    "box[r] holds the robot pose at pose row pairs[r, 1] expressed in the robot frame of the pose at row "
    "pairs[r, 0]: (x, y) = R(-theta_a) (p_b - p_a) [m], theta = theta_b - theta_a [rad, modulo 2 pi]"
)


@dataclass
class RelativePoses:
    """Relative pose enclosures (lidar mode with keyframes): ``box[r]`` holds (x, y, θ) of the
    robot at pose row ``pairs[r, 1]`` expressed in the robot frame at pose row ``pairs[r, 0]``
    (rows of ``Result.poses``): ``R(−θ_a)(p_b − p_a)`` and ``θ_b − θ_a`` (θ on the real line,
    the true difference modulo 2π is in it). An outer approximation like the pose boxes, and
    usually far tighter than what the two global boxes allow (those accumulate drift).
    """

    pairs: np.ndarray  # (R, 2) int64
    box: np.ndarray  # (R, 3, 2) float64
    definition: str = RELATIVE_DEFINITION

    def __len__(self) -> int:
        return int(self.pairs.shape[0])


@dataclass
class Landmarks:
    """Landmark boxes: ``box[l]`` holds (x, y) of landmark ``id[l]``.

    ``reference_id`` is None for an absolute (anchored / world-frame) map; otherwise the map
    is relative and ``box[l]`` holds ``m_id[l] − m_reference_id``.
    """

    id: np.ndarray  # (L,) int64
    box: np.ndarray  # (L, 2, 2) float64
    reference_id: int | None = None

    def __len__(self) -> int:
        return int(self.id.shape[0])


@dataclass
class PairSubpavings:
    """Per landmark pair (i, j): a subpaving enclosing dl = m_i − m_j.

    The boxes of pair ``p`` are ``boxes[offsets[p]:offsets[p+1]]`` with ``label`` ∈
    {LABEL_INNER, LABEL_BOUNDARY}; the outer approximation (it contains dl) is the union of
    all of them, the inner approximation (contained in the set) the inner-labelled ones.
    A pair with no box has an empty set (an inconsistency, recorded as an empty event).
    """

    i: np.ndarray  # (P,) int64
    j: np.ndarray  # (P,) int64
    offsets: np.ndarray  # (P+1,) int64
    boxes: np.ndarray  # (B, 2, 2) float64
    label: np.ndarray  # (B,) uint8

    def __len__(self) -> int:
        return int(self.i.shape[0])

    def pair_boxes(self, p: int) -> np.ndarray:
        return self.boxes[self.offsets[p] : self.offsets[p + 1]]


@dataclass
class MapGrid:
    """A cell-state grid (lidar mode).

    Cell ``state[r, c]`` covers ``[ox + c·res, ox + (c+1)·res] × [oy + r·res, oy + (r+1)·res]``
    (row = y index from the origin upwards). States: CELL_UNKNOWN, CELL_EMPTY (proven free
    for every pose in the enclosures: an inner approximation of free space), CELL_OBSTACLE
    (may hold a surface hit by a beam: the obstacle set is an outer approximation).
    """

    origin: np.ndarray  # (2,) float64: x, y of the corner of cell (0, 0)
    resolution: float
    state: np.ndarray  # (H, W) uint8
    #: :data:`GRID_PROVEN` (the states hold in the result's frame) or :data:`GRID_MOSAIC` (the
    #: submaps drawn at their anchors' box centres, for display: the guarantees are per submap)
    frame: str = "proven"

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.state.shape[0]), int(self.state.shape[1]))


GRID_PROVEN = "proven"
GRID_MOSAIC = "mosaic"


@dataclass
class Loops:
    """LiDAR loop closure: the anchor graph (nodes: the submaps' anchors, ``/submaps/anchor_box``
    after contraction) and the loop constraints found.

    - loop ``l``: pose row ``row[l]`` matched against the older submap ``submap[l]`` (its home
      submap then: ``home[l]``) over the search region ``prior[l]`` (the scan's pose in the old
      anchor's frame as the global boxes and the chain of anchors allow); ``box[l]`` holds the
      poses kept (outer; NaN when ``empty[l]``: no pose of the prior agreed, a contradiction of
      the data with the model, not used); ``beams[l]`` beams of the scan tested;
    - edge ``e``: ``edge_box[e]`` holds anchor ``edge_b[e]``'s robot pose in anchor ``edge_a[e]``'s
      frame (``edge_kind`` 0: chain / overlap, a scan tracked in both; 1: a loop took part);
    - ``anchor_box_open``: the anchor boxes from the chain alone met with dead reckoning (no loop
      edge), the reference the closure is measured against.
    """

    row: np.ndarray  # (L,) int64
    submap: np.ndarray  # (L,) int64
    home: np.ndarray  # (L,) int64
    prior: np.ndarray  # (L, 3, 2) float64
    box: np.ndarray  # (L, 3, 2) float64, NaN rows when empty
    beams: np.ndarray  # (L,) int64
    empty: np.ndarray  # (L,) bool
    edge_a: np.ndarray  # (E,) int64
    edge_b: np.ndarray  # (E,) int64
    edge_box: np.ndarray  # (E, 3, 2) float64
    edge_kind: np.ndarray  # (E,) int64
    anchor_box_open: np.ndarray  # (M, 3, 2) float64
    sweeps: int = 0

    def __len__(self) -> int:
        return int(self.row.shape[0])


@dataclass
class Submaps:
    """LiDAR submaps: local frames, each the robot pose at its anchor scan (pose row
    ``anchor[m]``), where the scans tracked in it have tight relative boxes and its map is proven.

    - ``anchor_box[m]`` holds the anchor's robot pose in the result's frame (the global tube);
    - submap ``m``'s map: ``grid(m)`` (cells of side ``resolution`` from ``origin[m]``, shape
      ``shape[m]``, states as :class:`MapGrid`), P_EMPTY and P_OBSTACLE in the anchor's frame;
    - its members ``member_row[member_offsets[m]:member_offsets[m + 1]]`` (pose rows), each with
      its box in the submap's frame ``member_box`` (outer: the true pose relative to the anchor's
      is inside) and whether it was mapped into the submap (``member_mapped``).
    """

    anchor: np.ndarray  # (M,) int64 pose rows
    anchor_box: np.ndarray  # (M, 3, 2) float64
    resolution: float
    origin: np.ndarray  # (M, 2) float64
    shape: np.ndarray  # (M, 2) int64: H, W
    state: np.ndarray  # (sum H·W,) uint8, row-major per submap
    member_offsets: np.ndarray  # (M + 1,) int64
    member_row: np.ndarray  # (K,) int64
    member_box: np.ndarray  # (K, 3, 2) float64
    member_mapped: np.ndarray  # (K,) bool

    def __len__(self) -> int:
        return int(self.anchor.shape[0])

    @property
    def cell_offsets(self) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(np.prod(self.shape, axis=1))]).astype(np.int64)

    def grid(self, m: int) -> MapGrid:
        """Submap ``m``'s map, in its anchor's frame."""
        o = self.cell_offsets
        h, w = (int(v) for v in self.shape[m])
        return MapGrid(origin=np.asarray(self.origin[m], float), resolution=float(self.resolution),
                       state=self.state[o[m]:o[m + 1]].reshape(h, w))

    def members(self, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rows, boxes, mapped)`` of submap ``m``."""
        a, b = int(self.member_offsets[m]), int(self.member_offsets[m + 1])
        return self.member_row[a:b], self.member_box[a:b], self.member_mapped[a:b]


@dataclass
class LogOddsGrid:
    """A log-odds occupancy grid on the geometry of ``Result.grid`` (lidar mode): the
    probabilistic baseline the interval map is compared with. **Not an enclosure and not
    guaranteed**: scans at the centres of their pose boxes, rays with no width or range error,
    the inverse sensor model ``l_occ`` (return cell) / ``l_free`` (crossed cells), clamped to
    ``[l_min, l_max]`` (see ``ivslam_cli.slam.lidar.logodds``).

    ``value[r, c]`` is the log-odds of cell (r, c) of the map grid: > 0 occupied (p > 0.5),
    < 0 free, 0 unknown. ``scans`` / ``beams``: how many went into it.
    """

    value: np.ndarray  # (H, W) float32, same shape as grid.state
    l_occ: float
    l_free: float
    l_min: float
    l_max: float
    scans: int = 0
    beams: int = 0


@dataclass
class EmptyEvents:
    """Every empty intersection: a proof that the data contradict the stated model.

    ``constraint`` names the constraint family (e.g. ``"pair_intersection"``,
    ``"observation"``, ``"motion"``); ``entity`` identifies what became empty: pair (i, j),
    landmark (id, −1) or pose (k, −1); ``measurement`` is the index of the offending
    measurement in its stream (−1 if none); ``text`` a short human description.
    """

    stamp: np.ndarray = field(default_factory=lambda: np.zeros(0))
    step: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    constraint: np.ndarray = field(default_factory=_str_array)
    entity: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    measurement: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    text: np.ndarray = field(default_factory=_str_array)

    def __len__(self) -> int:
        return int(self.stamp.shape[0])


@dataclass
class Rejections:
    """Measurements left out by the q-relaxed intersection: ``stream``, ``index``, ``reason``."""

    stream: np.ndarray = field(default_factory=_str_array)
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reason: np.ndarray = field(default_factory=_str_array)

    def __len__(self) -> int:
        return int(self.index.shape[0])


@dataclass
class WidthHistory:
    """Widths of one kind of enclosure over time, flat: one record per update.

    ``entity`` as in ``EmptyEvents``; ``definition`` states what the width is (e.g. "largest
    side of the hull of the outer approximation, metres"). The width of an empty set is
    recorded as NaN.
    """

    entity: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    step: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    stamp: np.ndarray = field(default_factory=lambda: np.zeros(0))
    width: np.ndarray = field(default_factory=lambda: np.zeros(0))
    definition: str = ""

    def __len__(self) -> int:
        return int(self.width.shape[0])


@dataclass
class Consistency:
    """The consistency record of a run.

    ``q`` is the q of the q-relaxed intersection per constraint family (0 = plain
    intersection); ``assumption`` states when the guarantee holds, e.g. "bounds hold for all
    but at most q observations per pair"; ``stopped`` is non-empty if the run stopped early
    (``--strict``) and says why.
    """

    empty_events: EmptyEvents = field(default_factory=EmptyEvents)
    q: dict[str, int] = field(default_factory=dict)
    rejected: Rejections = field(default_factory=Rejections)
    widths: dict[str, WidthHistory] = field(default_factory=dict)
    assumption: str = ""
    stopped: str = ""


@dataclass
class Result:
    """One run of one pipeline. Parts a mode does not produce are None."""

    mode: str
    provenance: ResultProvenance
    runtime_s: float
    poses: Poses | None = None
    landmarks: Landmarks | None = None
    pairs: PairSubpavings | None = None
    grid: MapGrid | None = None
    logodds: LogOddsGrid | None = None  # lidar: the probabilistic baseline (not guaranteed)
    relative: RelativePoses | None = None  # lidar: pose of one row in another's frame
    submaps: Submaps | None = None  # lidar: local frames, their maps and members
    loops: Loops | None = None  # lidar: loop constraints and the anchor graph
    global_map: MapGrid | None = None  # lidar with loop closure: every scan at its global box (proven)
    pose_sets: PoseSets | None = None  # landmarks: the union of boxes each pose box is the hull of
    robots: Robots | None = None  # several robots in one result: which pose (and truth) rows are whose
    consistency: Consistency = field(default_factory=Consistency)
    truth: GroundTruth | None = None
    stats: dict[str, float | int | str] = field(default_factory=dict)

    @property
    def main_map(self) -> MapGrid | None:
        """The map to show and export: the global map (proven in the result's frame) when it has
        cells, else ``grid``."""
        if self.global_map is not None and self.global_map.state.size:
            return self.global_map
        return self.grid

    def validate(self) -> None:
        """Raise ValueError if shapes/dtypes are inconsistent (a pipeline bug, not user input)."""
        _validate(self)


def _check(cond: bool, what: str) -> None:
    if not cond:
        raise ValueError(f"invalid Result: {what}")


def _validate(r: Result) -> None:
    _check(r.mode in MODES, f"mode {r.mode!r} not in {MODES}")
    if r.poses is not None:
        n = len(r.poses)
        _check(r.poses.stamp.shape == (n,), "poses.stamp must be (N,)")
        _check(r.poses.box.shape == (n, 3, 2), "poses.box must be (N, 3, 2)")
        _check(r.poses.frame in FRAMES, f"poses.frame must be one of {FRAMES}")
        if r.poses.submap is not None:
            _check(r.poses.submap.shape == (n,) and r.poses.submap.dtype.kind == "i", "poses.submap must be (N,) int")
            _check(r.poses.relative is not None and r.poses.relative.shape == (n, 3, 2), "poses.relative must be (N, 3, 2)")
    if r.submaps is not None:
        sm = r.submaps
        m = len(sm)
        _check(r.poses is not None, "submaps need the poses (anchors and members are pose rows)")
        _check(sm.anchor_box.shape == (m, 3, 2), "submaps.anchor_box must be (M, 3, 2)")
        _check(sm.origin.shape == (m, 2) and sm.shape.shape == (m, 2), "submaps.origin, shape must be (M, 2)")
        _check(sm.state.ndim == 1 and sm.state.dtype == np.uint8 and sm.state.shape[0] == int(sm.cell_offsets[-1]),
               "submaps.state must be flat uint8 of sum(H·W) cells")
        _check(sm.member_offsets.shape == (m + 1,) and int(sm.member_offsets[0]) == 0
               and int(sm.member_offsets[-1]) == sm.member_row.shape[0]
               and bool(np.all(np.diff(sm.member_offsets) >= 0)), "submaps.member_offsets")
        k = sm.member_row.shape[0]
        _check(sm.member_box.shape == (k, 3, 2) and sm.member_mapped.shape == (k,), "submaps member columns")
        npose = len(r.poses)
        _check(bool(np.all((sm.anchor >= 0) & (sm.anchor < npose)) and np.all((sm.member_row >= 0)
                                                                                & (sm.member_row < npose))),
               "submaps rows must be pose rows")
    if r.relative is not None:
        rp = r.relative
        m = len(rp)
        _check(r.poses is not None, "relative needs the poses (its pairs are pose rows)")
        _check(rp.pairs.shape == (m, 2) and rp.pairs.dtype.kind == "i", "relative.pairs must be (R, 2) int")
        _check(rp.box.shape == (m, 3, 2), "relative.box must be (R, 3, 2)")
        n = len(r.poses)
        _check(bool(np.all((rp.pairs >= 0) & (rp.pairs < n))), "relative.pairs must be pose rows in [0, N)")
        _check(bool(np.all(rp.box[..., 0] <= rp.box[..., 1])), "relative.box must have lo <= hi (no NaN, not empty)")
    if r.pose_sets is not None:
        ps = r.pose_sets
        _check(r.poses is not None and len(ps) == len(r.poses), "pose_sets.offsets must be (N+1,) for the N poses")
        _check(ps.boxes.ndim == 3 and ps.boxes.shape[1:] == (3, 2), "pose_sets.boxes must be (B, 3, 2)")
        _check(int(ps.offsets[0]) == 0 and int(ps.offsets[-1]) == ps.boxes.shape[0], "pose_sets.offsets ends")
        _check(bool(np.all(np.diff(ps.offsets) >= 0)), "pose_sets.offsets must be non-decreasing")
    if r.robots is not None:
        rb = r.robots
        m = len(rb)
        _check(r.poses is not None, "robots needs the poses (its offsets are pose rows)")
        _check(rb.pose_offsets.shape == (m + 1,) and rb.truth_offsets.shape == (m + 1,), "robots offsets must be (R+1,)")
        _check(int(rb.pose_offsets[0]) == 0 and int(rb.pose_offsets[-1]) == len(r.poses), "robots.pose_offsets ends")
        _check(bool(np.all(np.diff(rb.pose_offsets) >= 0)) and bool(np.all(np.diff(rb.truth_offsets) >= 0)),
               "robots offsets must be non-decreasing")
        g = 0 if r.truth is None or r.truth.pose is None else len(r.truth.pose)
        _check(int(rb.truth_offsets[0]) == 0 and int(rb.truth_offsets[-1]) == g, "robots.truth_offsets ends")
    if r.landmarks is not None:
        n = len(r.landmarks)
        _check(r.landmarks.id.shape == (n,), "landmarks.id must be (L,)")
        _check(r.landmarks.box.shape == (n, 2, 2), "landmarks.box must be (L, 2, 2)")
    if r.pairs is not None:
        p = r.pairs
        n = len(p)
        _check(p.j.shape == (n,), "pairs.j must be (P,)")
        _check(p.offsets.shape == (n + 1,), "pairs.offsets must be (P+1,)")
        _check(p.boxes.ndim == 3 and p.boxes.shape[1:] == (2, 2), "pairs.boxes must be (B, 2, 2)")
        _check(p.label.shape == (p.boxes.shape[0],), "pairs.label must be (B,)")
        _check(int(p.offsets[0]) == 0 and int(p.offsets[-1]) == p.boxes.shape[0], "pairs.offsets ends")
        _check(bool(np.all(np.diff(p.offsets) >= 0)), "pairs.offsets must be non-decreasing")
        _check(bool(np.all(np.isin(p.label, (LABEL_INNER, LABEL_BOUNDARY)))), "pairs.label values")
    for name, g in (("grid", r.grid), ("global_map", r.global_map)):
        if g is not None:
            _check(g.state.ndim == 2 and g.state.dtype == np.uint8, f"{name}.state must be (H, W) uint8")
            _check(g.frame in (GRID_PROVEN, GRID_MOSAIC), f"{name}.frame must be proven or mosaic")
            _check(np.asarray(g.origin).shape == (2,), f"{name}.origin must be (2,)")
            _check(g.resolution > 0, f"{name}.resolution must be > 0")
    if r.global_map is not None:
        _check(r.global_map.frame == GRID_PROVEN, "global_map.frame must be proven")
    if r.logodds is not None:
        lo = r.logodds
        _check(r.grid is not None, "logodds needs the map grid (it has its geometry)")
        _check(lo.value.dtype == np.float32 and lo.value.shape == r.grid.state.shape,
               "logodds.value must be float32 of the grid's shape")
        _check(lo.l_min < 0.0 < lo.l_max and lo.l_free < 0.0 < lo.l_occ, "logodds parameters")
    e = r.consistency.empty_events
    n = len(e)
    for name in ("step", "constraint", "measurement", "text"):
        _check(getattr(e, name).shape == (n,), f"empty_events.{name} must be (E,)")
    _check(e.entity.shape == (n, 2), "empty_events.entity must be (E, 2)")
    rej = r.consistency.rejected
    _check(rej.stream.shape == rej.index.shape == rej.reason.shape, "rejected columns differ in length")
    for kind, w in r.consistency.widths.items():
        _check(kind in WIDTH_KINDS, f"width kind {kind!r} not in {WIDTH_KINDS}")
        m = len(w)
        _check(w.entity.shape == (m, 2), f"widths[{kind}].entity must be (W, 2)")
        _check(w.step.shape == w.stamp.shape == (m,), f"widths[{kind}] columns differ in length")

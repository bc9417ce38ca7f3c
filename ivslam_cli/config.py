"""The resolved run configuration: documented defaults ← log-stated bounds ← TOML file ← options.

Every key lives in one table, :data:`KEYS` (section, name, default, type, unit, one-line
doc); ``docs/config.md`` is generated from it (``python -m ivslam_cli.config --markdown``,
``scripts/sync_docs.py``).
Sections: shared ``[bounds]`` (noise bounds) and ``[robust]`` (q-relaxation, strictness),
and one per mode: ``[pairs]``, ``[landmarks]``, ``[lidar]``. An unknown section or key, or a
value of the wrong type, is a one-line :class:`ConfigError` naming the key and the file.

Precedence, lowest first: the defaults below; bounds the log states about itself
(simulated logs record the bounds they were generated with: ``LogData.bounds``); the
``--config FILE``; command-line options. The resolved values (every key) go into the
result's provenance so a run can be reproduced.

Rounding: decimal constants such as ``0.1`` are not exact doubles. The loader returns the
nearest float; the interval kernels enclose every bound value by widening it outward by
one ulp before use, so the interval they use contains the decimal one.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ivslam_cli.errors import ConfigError

SECTIONS: dict[str, str] = {
    "bounds": "noise bounds shared by every mode (the kernels widen each by one ulp outward)",
    "robust": "robust handling of inconsistent data (q-relaxed intersection, strictness)",
    "pairs": "the pairs pipeline (Mustafa, Codres & Stancu): pairwise landmark displacement subpavings",
    "landmarks": "the landmark CSP pipeline (the Guaranteed SLAM slides' CSP over all poses and landmarks)",
    "lidar": "the feature-less LiDAR pipeline (the Guaranteed SLAM slides' P_EMPTY / P_OBSTACLE map)",
}

# Value types: "float" (int accepted), "int", "bool", "str", "int?" (int, unset = None),
# "float2" (two floats), "interval" (two floats lo <= hi), "float3" (three floats),
# "float3?" (three floats, unset = None).
TYPES = ("float", "int", "bool", "str", "int?", "float2", "interval", "float3", "float3?")

#: the largest integer any key takes (the kernels use 32-bit-safe counters; larger is a mistake)
INT_MAX = 2 ** 31 - 1
#: the largest noise bound in metres (and per-unit relative bounds) a key takes: wider proves nothing
BOUND_MAX = 1e4


@dataclass(frozen=True)
class Key:
    """One configuration key. ``minimum`` (with ``strict_min``) and ``maximum`` bound numeric
    values (each number of a list, too). Every number must be finite, and every integer at
    most :data:`INT_MAX`, whatever the key says."""

    section: str
    name: str
    default: Any
    type: str
    doc: str
    unit: str = ""
    minimum: float | None = None
    strict_min: bool = False
    maximum: float | None = None

    @property
    def dotted(self) -> str:
        return f"{self.section}.{self.name}"


KEYS: tuple[Key, ...] = (
    # --- [bounds]: |true − measured| ≤ bound
    Key("bounds", "range_abs", 0.1, "float", "absolute range bound: |ρ − z_ρ| ≤ range_abs + range_rel·z_ρ", "m", 0.0, maximum=BOUND_MAX),
    Key("bounds", "range_rel", 0.0, "float", "range bound proportional to the measured range", "", 0.0, maximum=10.0),
    Key("bounds", "bearing", 0.05, "float", "bearing bound: |α − z_α| ≤ bearing", "rad", 0.0, maximum=2 * math.pi),
    Key("bounds", "odom_trans_abs", 0.0, "float", "odometry translation bound per step (absolute)", "m", 0.0, maximum=BOUND_MAX),
    Key("bounds", "odom_trans_rel", 0.0, "float", "odometry translation bound per metre travelled", "", 0.0, maximum=10.0),
    Key("bounds", "odom_rot_abs", 0.0, "float", "odometry rotation bound per step (absolute)", "rad", 0.0, maximum=2 * math.pi),
    Key("bounds", "odom_rot_rel", 0.0, "float", "odometry rotation bound per radian turned", "", 0.0, maximum=10.0),
    Key("bounds", "odom_v", 0.0, "float", "twist odometry: speed bound |z_v − v| ≤ odom_v + odom_v_rel·|v| (v the true speed)", "m/s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "odom_v_rel", 0.0, "float", "twist odometry: speed bound proportional to the true speed", "", 0.0, maximum=10.0),
    Key("bounds", "odom_w", 0.0, "float", "twist odometry: turn-rate bound |z_ω − ω| ≤ odom_w + odom_w_rel·|v|", "rad/s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "odom_lag_xy", 0.0, "float", "twist odometry: the true position stays within this of the one the twist bounds drive (lag of commanded velocities, transients)", "m", 0.0, maximum=BOUND_MAX),
    Key("bounds", "odom_lag_th", 0.0, "float", "twist odometry: the true heading stays within this of the one the twist bounds drive", "rad", 0.0, maximum=2 * math.pi),
    Key("bounds", "odom_lag_time", 0.0, "float", "twist odometry: the drive follows its commands this late: the lag bounds grow by odom_lag_time × the largest commanded |v| (position) and |ω| (heading) over the last odom_lag_memory seconds", "s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "odom_lag_memory", 2.0, "float", "twist odometry: the window of past commands odom_lag_time applies to (a few time constants of the drive)", "s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "odom_w_rel", 0.0, "float", "twist odometry: turn-rate bound proportional to the true speed", "rad/m", 0.0, maximum=BOUND_MAX),
    Key("bounds", "speed_max", 0.0, "float", "the robot's top speed, |v| ≤ speed_max at every instant (a platform limit); bounds the motion within an odometry step, e.g. while a LiDAR takes its beams (lidar.sweep); 0: none stated", "m/s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "turn_rate_max", 0.0, "float", "the robot's top turn rate, |ω| ≤ turn_rate_max at every instant; see speed_max; 0: none stated", "rad/s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "accel_max", 0.0, "float", "pose-increment odometry: the robot's top acceleration, |p''| ≤ accel_max (turns included); within an odometry step the position then strays from the step's chord by at most accel_max·t·(h − t)/2, which lets the matcher take each beam of a LiDAR scan from its sensor moved by the step's nominal motion (lidar.sweep; scans stamped at an odometry stamp); 0: none stated", "m/s²", 0.0, maximum=BOUND_MAX),
    Key("bounds", "scan_time", 0.0, "float", "every beam of a LiDAR scan is taken within this of its nominal time (lidar.sweep counted from the scan's stamp, or from its tick of the fitted clock: lidar.scan_clock); each beam is deskewed to its nominal time and every pose widened by the motion in this time", "s", 0.0, maximum=BOUND_MAX),
    Key("bounds", "turn_accel_max", 0.0, "float", "pose-increment odometry: the robot's top angular acceleration, |θ''| ≤ turn_accel_max; within an odometry step the heading then strays from the step's chord by at most turn_accel_max·t·(h − t)/2, which lets a LiDAR scan's beams be turned by the step's nominal turn (lidar.sweep) and its poses widened only by the rest; 0: none stated (every pose widened by the whole turn)", "rad/s²", 0.0, maximum=BOUND_MAX),
    # --- [robust]
    Key("robust", "q_pair", 0, "int", "q-relaxed intersection per pair: tolerate up to q inconsistent observations (0 = plain intersection)", "", 0),
    Key("robust", "q_landmark", 0, "int", "landmarks mode: inconsistent observations tolerated per landmark (q-relaxed intersection of its observations)", "", 0),
    Key("robust", "q_landmark_frac", 0.0, "float", "landmarks mode: ... or this fraction of the landmark's observations, whichever is larger", "", 0.0),
    Key("robust", "q_pose", 0, "int", "landmarks mode: inconsistent observations tolerated at each pose (with robust.q_pose_scope = window: among all those within landmarks.pose_window of a pose)", "", 0),
    Key("robust", "q_pose_scope", "node", "str", "landmarks mode: what q_pose counts — window: at most q_pose wrong among the observations within landmarks.pose_window of each pose; node: at most q_pose at each pose, so a window tolerates q_pose at each pose its observations come from, at most q of a landmark's (the assumption of pose_window = 0, kept over longer windows)"),
    Key("robust", "strict", False, "bool", "stop at the first empty intersection instead of applying the q policy"),
    # --- [pairs]
    Key("pairs", "heading", (0.0, 0.0), "interval", "known heading interval [lo, hi] at every step; with heading_source = odometry, the bound added to the odometry heading", "rad"),
    Key("pairs", "heading_source", "option", "str", "where the heading comes from: option (the heading interval) or odometry (the log's odometry poses, per step)"),
    Key("pairs", "eps", 0.05, "float", "resolution ε of the subpavings: boxes narrower than ε are not bisected", "m", 1e-6),
    Key("pairs", "anchor_id", None, "int?", "id of the anchoring landmark (known position); unset: relative map"),
    Key("pairs", "anchor_xy", (0.0, 0.0), "float2", "position [x, y] of the anchoring landmark", "m"),
    Key("pairs", "reference_id", None, "int?", "landmark a relative map is expressed against; unset: the smallest id"),
    Key("pairs", "max_pairs", 10_000, "int", "safety limit: error out beyond this many landmark pairs", "", 1, maximum=1_000_000),
    Key("pairs", "max_boxes", 100_000, "int", "safety limit on the boxes of one pair's subpaving", "", 1, maximum=10_000_000),
    Key("pairs", "max_work", 20_000_000, "int", "safety limit on the work of the whole run: box tests of the subpavings (0.1–0.2 M/s on one core); beyond it the run stops with an error naming this key", "", 1),
    Key("landmarks", "initial_pose", None, "float3?", "initial pose [x, y, θ] (the map frame's anchor); unset: from the truth with --initial-pose-from-truth, else the origin", "m, m, rad"),
    Key("landmarks", "initial_pose_from_truth", False, "bool", "take the initial pose from the log's ground truth (interpolated at the first odometry stamp)"),
    Key("landmarks", "initial_margin", (0.01, 0.01, 0.01), "float3", "half-widths of the initial pose box around initial_pose", "m, m, rad", 0.0),
    Key("landmarks", "pose_window", 2.0, "float", "observations within this time of a pose join its q-relaxed intersection (each carried to the pose by the motion possible in between); 0: only the pose's own", "s", 0.0),
    Key("landmarks", "pose_slices", 256, "int", "pose sets: the circle of headings is cut into this many fixed slices and each pose is a union of at most one (x, y, θ) box per slice (what falls into a slice is merged into its box); the hull is the pose box", "", 4, maximum=1024),
    Key("landmarks", "pose_window_obs", 16, "int", "at most this many observations join a pose's q-relaxed intersection: its own, then the others of its window nearest in time (a subset of the window: the same assumption holds)", "", 1),
    Key("landmarks", "pose_pieces", 8, "int", "a slice of a pose set with at most 8 slices (a heading not lost) is paved by at most this many boxes when its observations contract it (set inversion in pose space: each box bisected across its widest side, x, y or θ times the observed range; 1: the slice as one box)", "", 1, maximum=4096),
    Key("landmarks", "skip_levels", 6, "int", "skip edges: each node with observations is also linked to the nodes with observations 2, 4, …, 2^skip_levels frames later (and to the next one past nodes without) by the composed motion increment, contracted in the sweeps like a motion step (the relation between the two poses kept whole instead of through the heading slices of every node between); 0: none", "", 0, maximum=16),
    Key("landmarks", "map_known", False, "bool", "localisation only: the landmark map is given, each landmark box fixed to its true position (the log's ground truth) ± map_margin; the floor the bounds allow for the poses, beside the SLAM run (the frame is the truth's)"),
    Key("landmarks", "map_margin", 0.0, "float", "with map_known: half-width of each given landmark box around its true position (the truth's own error)", "m", 0.0, maximum=BOUND_MAX),
    Key("landmarks", "max_step", 0.5, "float", "twist odometry: steps longer than this are cut (the step model's error grows with dt²); 0: never cut", "s", 0.0),
    Key("landmarks", "max_iterations", 30, "int", "cap on forward-backward sweeps over the trajectory", "", 1, maximum=100_000),
    Key("landmarks", "tolerance", 1e-3, "float", "stop when a sweep shrinks the summed widths by less than this fraction", "", 0.0),
    # --- [lidar]: range/bearing bounds of the beams are [bounds] range_abs, range_rel, bearing
    Key("lidar", "eps", 0.05, "float", "cell side ε of the map grid", "m", 1e-3),
    Key("lidar", "max_range", 0.0, "float", "valid returns longer than this are treated as no return (they prove nothing); 0: the scan's own range_max", "m", 0.0),
    Key("lidar", "motion", "auto", "str", "dead reckoning from: twist (v, ω with odom_v/odom_w bounds), pose (odometry pose increments with odom_trans/odom_rot bounds), or auto (the stream whose bounds are set; twist if both or neither)"),
    Key("lidar", "max_pose_width", 2.0, "float", "scans whose robot pose box (in their submap's frame; with poses_known, the given one) is wider than this in x or y are not mapped (they would prove no free space and mark obstacle rings metres wide), nor matched in an older submap still tracking them (the newest one does); 0: map every scan (the global map after loop closure still takes only boxes of at most 2 m)", "m", 0.0),
    Key("lidar", "max_step", 0.5, "float", "twist odometry: steps longer than this are cut (the step model's error grows with dt²); 0: never cut", "s", 0.0),
    Key("lidar", "fill_gaps", False, "bool", "when the bearing bound is below half the beam step (beam cones that do not touch), take the gap between two beams as free up to the nearer free range — an assumption (nothing pokes between two adjacent beams), stated in the result; false: such scans prove no free space"),
    Key("lidar", "contract", True, "bool", "contract each scan's pose box in its submap's frame against the submap's anchor scan and map (set inversion in pose space; dead-reckoning runs only)"),
    Key("lidar", "q_beams", 5, "int", "scan-to-submap matching: beams of a scan allowed to end in proven-free space, and beam ends of the scans matched against allowed in its free space (moving people, glass, beams the static-world model does not explain)", "", 0),
    Key("lidar", "q_retry", 20, "int", "when no pose of a scan's predicted box agrees with its submap with q_beams beams allowed, it is matched again allowing this many (more than q_beams: else no retry) before lidar.relocalise doubts the motion step; the scans kept so are recorded (empty event q_relaxed) and named in the assumption", "", 0),
    Key("lidar", "sweep", 0.0, "float", "time from a scan's stamp to its last beam (a 2D LiDAR takes its beams one after another while the robot moves: the URG-04LX 683 of 1024 steps of a 100 ms turn, 0.067 s; sensor_msgs/LaserScan stamps the first beam; negative: the stamp is the last beam's); each beam is turned, and in the matcher's rule A and the map moved, by the odometry's nominal motion to its time, every pose widened by how far the motion may stray from it (with pose increments the whole motion, unless bounds.turn_accel_max and accel_max are stated); free space only where adjacent cones overlap by the turn between two beams; 0: every beam at the scan's stamp (tracked runs; with poses_known the given poses are the beams')", "s"),
    Key("lidar", "scan_clock", "stamps", "str", "when each scan was taken: stamps (at its stamp, as lidar.sweep says), or fitted (on the sensor's own regular clock fitted to the stamps: a spinning LiDAR takes a scan every turn while a logger stamps it when it reads it, with a latency that jitters; a scan repeating the previous one's ranges is that one read again, at its time); either within bounds.scan_time (tracked runs; with poses_known the given poses are the beams')"),
    Key("lidar", "sweep_from_log", True, "bool", "where the log records the time between two beams (sensor_msgs/LaserScan time_increment), a scan's sweep is that × (beams − 1), not lidar.sweep"),
    Key("lidar", "q_hold", 1.0, "float", "after a q-relaxed scan, the scans of the next this many seconds are matched allowing q_retry beams from the start (whatever broke the static world, people or glass, is likely still there, and a scan with more than q_beams such beams may still agree with some wrong pose); recorded (scans_q_held) and named in the assumption; 0: only the scans that fail with q_beams", "s", 0.0),
    Key("lidar", "submap_distance", 2.0, "float", "a new submap starts at the scan that is this far from the current submap's anchor (dead reckoning: every scan is tracked and mapped in the frame of its submap's anchor scan)", "m", 0.0, True),
    Key("lidar", "submap_turn", 1.0, "float", "… or has turned this much from it", "rad", 0.0, True),
    Key("lidar", "submap_width", 0.4, "float", "… or whose pose box in the submap's frame is this wide in x or y", "m", 0.0, True),
    Key("lidar", "submap_overlap", 0.5, "float", "a submap keeps tracking and mapping the scans of this much travel after the next one starts (consecutive submaps overlap)", "m", 0.0),
    Key("lidar", "match_boxes", 2000, "int", "scan-to-submap matching: pose sub-boxes tested per scan at most (the budget of the bound searches; a search out of budget keeps every pose it did not exclude)", "", 1, maximum=1_000_000),
    Key("lidar", "match_stride", 4, "int", "scan-to-submap matching: every n-th beam of the scan, and of the scans it is matched against, is tested", "", 1),
    Key("lidar", "match_resolution", 0.02, "float", "scan-to-submap matching: the bounds of the pose set are found to this resolution in x, y and in beam-end motion (median range × θ)", "m", 0.0, True),
    Key("lidar", "match_heading_resolution", 0.005, "float", "scan-to-submap matching: the heading's two bounds are found to this finer resolution (sub-boxes this small in x, y and median range × θ; the heading width sets how far the scan's beams can swing); the slices' x and y bounds to match_resolution", "m", 0.0, True),
    Key("lidar", "match_slices", 8, "int", "scan-to-submap matching: the pose set kept per scan as at most this many boxes (one per heading slice)", "", 1),
    Key("lidar", "map_sets", True, "bool", "map each tracked scan with its match's pose set too: the cells every box of the set (one per heading slice) proves free are added to its hull's (P_EMPTY of a union is the intersection of its boxes'; see docs/lidar.md); false: the hull only"),
    Key("lidar", "relocalise", (0.5, 0.5), "float2", "when no pose of a scan's predicted box agrees with its submap (the motion step broke its bounds, an odometry jump, or more than q_beams beams did), the scan is matched again over its box widened by this much in x, y [m] and θ [rad]; a pose found there is kept, the step recorded as an outlier and the assumption relaxed to say so; [0, 0]: never (the box is kept, an empty event)", "m, rad"),
    Key("lidar", "loop_closure", True, "bool", "match scans against older submaps they may be in (loop constraints) and contract the anchor graph to a fixpoint (dead-reckoning runs only)"),
    Key("lidar", "loop_every", 5, "int", "loop closure: every n-th scan is searched for loops", "", 1),
    Key("lidar", "loop_window", (3.0, 1.5), "float2", "loop closure: an older submap is searched only when the scan's pose in its anchor's frame (what the global boxes and the chain of anchors allow) is at most this wide in x, y [m] and θ [rad]", "m, rad", 0.0),
    Key("lidar", "loop_wide", 8.0, "float", "loop closure: a prior wider than loop_window but at most this wide in x and y [m], any heading, is paved first (every 4th beam, leaves of 0.25 m) and its kept leaves matched; 0 = off", "m", 0.0),
    Key("lidar", "loop_candidates", 2, "int", "loop closure: at most this many older submaps are searched per scan (the longest chain first: the oldest submap, then the narrowest prior)", "", 1),
    Key("lidar", "loop_stride", 1, "int", "loop closure: every n-th beam of the scan, and of the old submap's anchor scan, is tested", "", 1),
    Key("lidar", "loop_boxes", 8000, "int", "loop closure: pose sub-boxes tested per loop search at most (a search out of budget keeps every pose it did not exclude)", "", 1),
    Key("lidar", "pair_boxes", 0, "int", "scan pairs: each scan also matched against the scan before it alone (that scan's frame exact, the motion model's step box the prior), giving an enclosure of their relative pose (the scan-to-scan relations of benchmarks) beside the submaps' chain, and each scan's prior in a submap holding the scan before it met with that scan's box ⊕ the pair (where the submap holds it alone, the pair is the match); the pose sub-boxes tested per pair at most; 0: no pairs", "", 0, maximum=1_000_000),
    Key("lidar", "pair_stride", 1, "int", "scan pairs: every n-th beam of both scans is tested", "", 1),
    Key("lidar", "pair_resolution", 0.01, "float", "scan pairs: the hull's x and y bounds are found to this resolution (its heading to match_heading_resolution)", "m", 0.0, True),
    Key("lidar", "threads", 0, "int", "tracking: a scan's submaps (the overlapping ones) are matched and mapped in this many threads, with the same results as in one; 0: the cores this process may run on (a batch's workers run one each)", "", 0, maximum=1024),
    Key("lidar", "poses_known", False, "bool", "guaranteed mapping only: the poses are given (known_poses) within pose_margin; no odometry needed"),
    Key("lidar", "known_poses", "auto", "str", "with poses_known, where the poses come from: truth (the log's ground truth), scan (poses recorded with each scan, e.g. CARMEN FLASER), odometry (odometry poses), or auto (the first of these the log has); interpolated at scan stamps between given poses"),
    Key("lidar", "pose_margin", (0.05, 0.05, 0.01), "float3", "with poses_known: half-widths of the pose box around each given pose (must cover their error and any interpolation)", "m, m, rad", 0.0),
)

KEYS_BY_NAME: dict[str, Key] = {k.dotted: k for k in KEYS}

#: Bounds a log states under another name (simulated LiDAR logs: the beam angle error is the
#: bearing bound of a beam).
LOG_BOUND_ALIASES: dict[str, str] = {"beam_angle": "bearing"}


@dataclass
class Config:
    """Resolved values by section, and where each came from (default/log/file path/option)."""

    values: dict[str, dict[str, Any]]
    sources: dict[str, str] = field(default_factory=dict)
    ignored_log_bounds: list[str] = field(default_factory=list)

    def __getitem__(self, dotted: str) -> Any:
        section, _, name = dotted.partition(".")
        try:
            return self.values[section][name]
        except KeyError:
            raise KeyError(f"no configuration key {dotted!r}") from None

    def section(self, name: str) -> dict[str, Any]:
        return dict(self.values[name])

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """JSON-safe copy (tuples as lists) for the result's provenance."""
        return {s: {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()} for s, d in self.values.items()}


def _coerce(key: Key, value: Any, where: str) -> Any:
    """Check ``value`` against ``key.type``; return it normalised (floats, tuples)."""
    label = f"[{key.section}] {key.name}"

    def bad(expected: str) -> ConfigError:
        return ConfigError(f"{label} must be {expected}, got {value!r}", where)

    def as_float(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise bad("a number" if key.type == "float" else "a list of two numbers")
        try:
            x = float(v)
        except OverflowError:
            raise bad("a finite number") from None
        if not math.isfinite(x):
            raise bad("a finite number (not NaN or infinite)")
        return x

    t = key.type
    if t == "float":
        out: Any = as_float(value)
    elif t in ("int", "int?"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise bad("an integer")
        out = int(value)
    elif t == "bool":
        if not isinstance(value, bool):
            raise bad("true or false")
        out = value
    elif t == "str":
        if not isinstance(value, str):
            raise bad("a string")
        out = value
    elif t in ("float3", "float3?"):
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise bad("a list of three numbers")
        out = (as_float(value[0]), as_float(value[1]), as_float(value[2]))
    elif t in ("float2", "interval"):
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise bad("a list of two numbers")
        out = (as_float(value[0]), as_float(value[1]))
        if t == "interval" and not out[0] <= out[1]:
            raise bad("an interval [lo, hi] with lo <= hi")
    else:  # pragma: no cover - table error
        raise AssertionError(t)
    numbers = (out if isinstance(out, tuple) else (out,)) if not isinstance(out, (bool, str)) else ()
    for x in (v for v in numbers if v is not None):
        if t in ("int", "int?") and abs(x) > INT_MAX:
            raise bad(f"an integer of at most {INT_MAX}")
        if key.minimum is not None and (x < key.minimum or (key.strict_min and x == key.minimum)):
            raise bad(f"{'>' if key.strict_min else '>='} {key.minimum:g}")
        if key.maximum is not None and x > key.maximum:
            raise bad(f"<= {key.maximum:g}")
    return out


def load_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML config file; unreadable or invalid TOML is a one-line ConfigError."""
    from ivslam_cli import limits
    from ivslam_cli.inputs import check_input

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    path = Path(path)
    if not os.path.lexists(path):
        raise ConfigError("config file not found", path)
    check_input(path, "TOML config file", error=ConfigError)  # no FIFO, device, directory
    try:
        limits.check("JSON_BYTES", path.stat().st_size, "the config file's size")
        with open(path, "rb") as f:
            return tomllib.load(f)
    except limits.LimitExceeded as exc:
        raise exc.about(path) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"invalid TOML: {str(exc).splitlines()[0]}", path) from None
    except UnicodeDecodeError:
        raise ConfigError("invalid TOML: not UTF-8 text", path) from None
    except RecursionError:
        raise ConfigError("invalid TOML: nested too deeply", path) from None
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path) from None


def _file_layer(data: Mapping[str, Any], where: str) -> dict[str, Any]:
    layer: dict[str, Any] = {}
    for section, table in data.items():
        if section not in SECTIONS:
            raise ConfigError(
                f"unknown section or top-level key {section!r} (sections: {', '.join(f'[{s}]' for s in SECTIONS)})",
                where,
            )
        if not isinstance(table, Mapping):
            raise ConfigError(f"{section!r} must be a section [{section}], got {table!r}", where)
        for name, value in table.items():
            key = KEYS_BY_NAME.get(f"{section}.{name}")
            if key is None:
                known = ", ".join(k.name for k in KEYS if k.section == section) or "none yet"
                raise ConfigError(f"unknown key {name!r} in [{section}] (known: {known})", where)
            layer[key.dotted] = _coerce(key, value, where)
    return layer


def resolve_config(
    config_file: str | Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    log_bounds: Mapping[str, float] | None = None,
) -> Config:
    """Defaults ← ``log_bounds`` ← ``config_file`` ← ``overrides`` (dotted keys; None = not given).

    ``log_bounds`` keys are ``[bounds]`` names (``range_abs`` or ``bounds.range_abs``);
    those that are not config keys are listed in ``Config.ignored_log_bounds``, not applied.
    """
    values: dict[str, dict[str, Any]] = {s: {} for s in SECTIONS}
    sources: dict[str, str] = {}
    for k in KEYS:
        values[k.section][k.name] = k.default
        sources[k.dotted] = "default"

    ignored: list[str] = []
    for name, value in (log_bounds or {}).items():
        name = LOG_BOUND_ALIASES.get(name, name)
        dotted = name if "." in name else f"bounds.{name}"
        key = KEYS_BY_NAME.get(dotted)
        if key is None or key.section != "bounds":
            ignored.append(name)
            continue
        values[key.section][key.name] = _coerce(key, value, "bounds stated by the log")
        sources[dotted] = "log"

    if config_file is not None:
        where = str(config_file)
        for dotted, value in _file_layer(load_toml(config_file), where).items():
            key = KEYS_BY_NAME[dotted]
            values[key.section][key.name] = value
            sources[dotted] = where

    for dotted, value in (overrides or {}).items():
        if value is None:
            continue
        key = KEYS_BY_NAME.get(dotted)
        if key is None:
            raise ConfigError(f"unknown configuration key {dotted!r}", "command line")
        values[key.section][key.name] = _coerce(key, value, "command line")
        sources[dotted] = "option"
    return Config(values=values, sources=sources, ignored_log_bounds=ignored)


def _fmt_default(v: Any) -> str:
    if v is None:
        return "unset"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, tuple):
        return "[" + ", ".join(repr(x) for x in v) + "]"
    return repr(v)


def _fmt_range(k: Key) -> str:
    parts = []
    if k.minimum is not None:
        parts.append(f"{'>' if k.strict_min else '≥'} {k.minimum:g}")
    if k.maximum is not None:
        parts.append(f"≤ {k.maximum:g}")
    return f" ({', '.join(parts)})" if parts else ""


def markdown_table() -> str:
    """The configuration reference as a markdown table (one row per key, grouped by section)."""
    lines = [
        "| key | default | type | unit | meaning |",
        "|---|---|---|---|---|",
    ]
    for section, doc in SECTIONS.items():
        keys = [k for k in KEYS if k.section == section]
        lines.append(f"| **[{section}]** | | | | {doc}{'' if keys else ' (no keys yet)'} |")
        for k in keys:
            lines.append(f"| `{k.name}` | `{_fmt_default(k.default)}` | {k.type} | {k.unit} | {k.doc}{_fmt_range(k)} |")
    lines.append("")
    lines.append(
        f"Every number must be finite, and every integer at most {INT_MAX}; a value outside the range "
        "given above is a one-line error naming the key."
    )
    lines.append("")
    lines.append(
        "Decimal values such as 0.1 are not exact doubles: the loader returns the nearest float and the "
        "interval kernels widen every bound outward by one ulp, so the bound used contains the decimal one."
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args != ["--markdown"]:
        print("usage: python -m ivslam_cli.config --markdown", file=sys.stderr)
        return 2
    print(markdown_table())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Parameters of the LiDAR pipeline, read once from the resolved configuration."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ivslam_cli.errors import ConfigError
from ivslam_cli.interval.vector import bound_up
from ivslam_cli.slam.lidar.map_update import LidarBounds
from ivslam_cli.slam.lidar.scan_clock import CLOCKS
from ivslam_cli.slam.motion import InitialPose, MotionBounds

MOTIONS = ("auto", "twist", "pose")
KNOWN_SOURCES = ("auto", "truth", "scan", "odometry")


def beam_bounds(range_abs: float, range_rel: float, bearing: float, fill_gaps: bool) -> LidarBounds:
    """The beam bounds of ``[bounds]`` in the map kernels' convention.

    ``[bounds]`` states ``|ρ − z| ≤ range_abs + range_rel·z`` (measured range) and simulated logs
    ``… + range_rel·ρ`` (true range); the map kernels take the second form, with
    ``range_abs / (1 − range_rel)`` and ``range_rel / (1 − range_rel)``, which holds in both
    conventions (rounded up)."""
    a = bound_up(range_abs)
    r = bound_up(range_rel)
    if not r < 1.0 / 3.0:
        raise ConfigError(f"[bounds] range_rel = {range_rel} must be < 1/3 in lidar mode")
    den = float(np.nextafter(1.0 - r, -np.inf)) if r else 1.0
    a2 = float(np.nextafter(a / den, np.inf)) if r else a
    r2 = float(np.nextafter(r / den, np.inf)) if r else 0.0
    b = LidarBounds(a2, r2, bound_up(bearing), fill_gaps=bool(fill_gaps))
    b.check()
    return b


@dataclass(frozen=True)
class Params:
    """``[bounds]`` (beam and odometry bounds), ``[robust] strict``, the initial pose of
    ``[landmarks]`` and ``[lidar]`` (see the configuration table for every key)."""

    beams: LidarBounds  # in the map kernels' convention (see beam_bounds)
    odometry: MotionBounds
    initial: InitialPose
    strict: bool
    eps: float
    max_range: float
    motion: str  # auto / twist / pose
    max_pose_width: float
    max_step: float
    contract: bool
    q_beams: int
    q_retry: int
    q_hold: float
    sweep: float
    sweep_from_log: bool
    scan_clock: str
    scan_time: float
    submap_distance: float
    submap_turn: float
    submap_width: float
    submap_overlap: float
    match_boxes: int
    match_stride: int
    match_resolution: float
    match_heading_resolution: float
    relocalise: tuple[float, float]
    match_slices: int
    map_sets: bool
    poses_known: bool
    known_poses: str
    pose_margin: tuple[float, float, float]
    loop_closure: bool = True
    loop_every: int = 5
    loop_window: tuple[float, float] = (3.0, 1.5)
    loop_wide: float = 8.0
    loop_candidates: int = 2
    loop_boxes: int = 8000
    loop_stride: int = 1
    pair_boxes: int = 0
    pair_stride: int = 1
    pair_resolution: float = 0.01
    threads: int = 0

    @property
    def tracking(self) -> bool:
        """Scan by scan in submaps (dead reckoning), not given poses mapped in one frame."""
        return not self.poses_known

    @classmethod
    def from_config(cls, cfg) -> Params:
        motion = cfg["lidar.motion"]
        if motion not in MOTIONS:
            raise ConfigError(f"[lidar] motion must be one of {', '.join(MOTIONS)}, got {motion!r}")
        clock = cfg["lidar.scan_clock"]
        if clock not in CLOCKS:
            raise ConfigError(f"[lidar] scan_clock must be one of {', '.join(CLOCKS)}, got {clock!r}")
        known = cfg["lidar.known_poses"]
        if known not in KNOWN_SOURCES:
            raise ConfigError(f"[lidar] known_poses must be one of {', '.join(KNOWN_SOURCES)}, got {known!r}")
        return cls(
            beams=beam_bounds(cfg["bounds.range_abs"], cfg["bounds.range_rel"], cfg["bounds.bearing"],
                              cfg["lidar.fill_gaps"]),
            odometry=MotionBounds.from_config(cfg), initial=InitialPose.from_config(cfg),
            strict=bool(cfg["robust.strict"]), eps=float(cfg["lidar.eps"]), max_range=float(cfg["lidar.max_range"]),
            motion=motion, max_pose_width=float(cfg["lidar.max_pose_width"]), max_step=float(cfg["lidar.max_step"]),
            contract=bool(cfg["lidar.contract"]), q_beams=int(cfg["lidar.q_beams"]),
            q_retry=int(cfg["lidar.q_retry"]), q_hold=float(cfg["lidar.q_hold"]), sweep=float(cfg["lidar.sweep"]), sweep_from_log=bool(cfg["lidar.sweep_from_log"]),
            scan_clock=clock, scan_time=float(cfg["bounds.scan_time"]),
            submap_distance=float(cfg["lidar.submap_distance"]), submap_turn=float(cfg["lidar.submap_turn"]),
            submap_width=float(cfg["lidar.submap_width"]), submap_overlap=float(cfg["lidar.submap_overlap"]),
            match_boxes=int(cfg["lidar.match_boxes"]), match_stride=int(cfg["lidar.match_stride"]),
            match_resolution=float(cfg["lidar.match_resolution"]),
            match_heading_resolution=float(cfg["lidar.match_heading_resolution"]),
            relocalise=tuple(float(v) for v in cfg["lidar.relocalise"]),
            match_slices=int(cfg["lidar.match_slices"]), map_sets=bool(cfg["lidar.map_sets"]),
            poses_known=bool(cfg["lidar.poses_known"]), known_poses=known,
            pose_margin=tuple(float(v) for v in cfg["lidar.pose_margin"]),
            loop_closure=bool(cfg["lidar.loop_closure"]), loop_every=int(cfg["lidar.loop_every"]),
            loop_window=tuple(float(v) for v in cfg["lidar.loop_window"]),
            loop_wide=float(cfg["lidar.loop_wide"]),
            loop_candidates=int(cfg["lidar.loop_candidates"]), loop_boxes=int(cfg["lidar.loop_boxes"]),
            loop_stride=int(cfg["lidar.loop_stride"]), pair_boxes=int(cfg["lidar.pair_boxes"]),
            pair_stride=int(cfg["lidar.pair_stride"]), pair_resolution=float(cfg["lidar.pair_resolution"]),
            threads=int(cfg["lidar.threads"]),
        )

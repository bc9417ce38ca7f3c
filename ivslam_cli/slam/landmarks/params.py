"""Parameters of the landmark CSP pipeline, read once from the resolved configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ivslam_cli.errors import ConfigError
from ivslam_cli.slam.motion import InitialPose, MotionBounds

Q_POSE_SCOPES = ("window", "node")


def _scope(value) -> str:
    if value not in Q_POSE_SCOPES:
        raise ConfigError(f"[robust] q_pose_scope must be one of {', '.join(Q_POSE_SCOPES)}, got {value!r}")
    return str(value)


@dataclass(frozen=True)
class Params:
    """``[bounds]`` (observation and odometry bounds), ``[robust]`` (q per landmark and per
    pose, strict) and ``[landmarks]`` (see the configuration table)."""

    range_abs: float
    range_rel: float
    bearing: float
    odometry: MotionBounds
    initial: InitialPose
    q_landmark: int
    q_landmark_frac: float
    q_pose: int
    q_pose_scope: str  # window / node
    strict: bool
    pose_window: float
    pose_window_obs: int
    pose_slices: int
    pose_pieces: int
    max_step: float
    skip_levels: int
    map_known: bool
    map_margin: float
    max_iterations: int
    tolerance: float

    @classmethod
    def from_config(cls, cfg) -> Params:
        return cls(
            range_abs=float(cfg["bounds.range_abs"]), range_rel=float(cfg["bounds.range_rel"]),
            bearing=float(cfg["bounds.bearing"]), odometry=MotionBounds.from_config(cfg),
            initial=InitialPose.from_config(cfg), q_landmark=int(cfg["robust.q_landmark"]),
            q_landmark_frac=float(cfg["robust.q_landmark_frac"]), q_pose=int(cfg["robust.q_pose"]),
            q_pose_scope=_scope(cfg["robust.q_pose_scope"]),
            strict=bool(cfg["robust.strict"]), pose_window=float(cfg["landmarks.pose_window"]),
            pose_window_obs=int(cfg["landmarks.pose_window_obs"]),
            pose_slices=int(cfg["landmarks.pose_slices"]), pose_pieces=int(cfg["landmarks.pose_pieces"]), max_step=float(cfg["landmarks.max_step"]),
            skip_levels=int(cfg["landmarks.skip_levels"]),
            map_known=bool(cfg["landmarks.map_known"]), map_margin=float(cfg["landmarks.map_margin"]),
            max_iterations=int(cfg["landmarks.max_iterations"]), tolerance=float(cfg["landmarks.tolerance"]),
        )

"""The in-memory log model every pipeline consumes, whatever the file format.

All streams are time-sorted numpy arrays (stamps in seconds, float64). Ragged data
(scans with varying beam counts) are stored flat with an ``offsets`` array of length
``n + 1``: the ranges of scan ``k`` are ``ranges[offsets[k]:offsets[k+1]]``.
Readers fill what the log has and leave the rest ``None``; ``provenance.dropped``
says what was removed and why (no-return beams, unknown barcodes, unsorted stamps...).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Scans:
    """2D LiDAR scans (``sensor_msgs/LaserScan`` semantics).

    ``ranges`` is float32 and keeps every beam (so beam ``i`` has angle
    ``angle_min + i * angle_increment``); ``valid`` marks the beams that are a real return
    (finite, within ``[range_min, range_max]``, not an error code). Invalid beams prove
    no obstacle; pipelines decide what free space, if any, they may still prove.
    ``mount`` is the laser pose on the robot ``(x, y, yaw)`` in the base frame.
    """

    stamp: np.ndarray  # (S,) float64
    angle_min: np.ndarray  # (S,) float64
    angle_increment: np.ndarray  # (S,) float64
    range_min: np.ndarray  # (S,) float64
    range_max: np.ndarray  # (S,) float64
    offsets: np.ndarray  # (S+1,) int64
    ranges: np.ndarray  # (B,) float32
    valid: np.ndarray  # (B,) bool
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame_id: str = ""
    # (S,) float64 seconds between two beams (sensor_msgs/LaserScan time_increment; NaN where a
    # scan does not say); None when the log records none
    time_increment: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.stamp.shape[0])


@dataclass
class Odometry:
    """Odometry: poses in the odometry frame and/or body velocities.

    ``pose`` is ``(N, 3)`` = x, y, theta (None if the log carries only velocities);
    ``twist`` is ``(N, 2)`` = v [m/s], omega [rad/s] (None if only poses).
    """

    stamp: np.ndarray  # (N,)
    pose: np.ndarray | None = None  # (N, 3)
    twist: np.ndarray | None = None  # (N, 2)

    def __len__(self) -> int:
        return int(self.stamp.shape[0])


@dataclass
class Observations:
    """Range-bearing landmark observations (bearing in the robot frame, rad)."""

    stamp: np.ndarray  # (M,)
    landmark_id: np.ndarray  # (M,) int64
    range: np.ndarray  # (M,) float64
    bearing: np.ndarray  # (M,) float64

    def __len__(self) -> int:
        return int(self.stamp.shape[0])


@dataclass
class GroundTruth:
    """What the log knows of the truth (any part may be missing).

    ``outliers`` maps a stream name (``"observations"``, ``"scans"``, ``"odometry"``) to a
    boolean mask of the measurements known to break the stated bounds (simulated logs).
    ``world`` is a set of wall segments ``(K, 4)`` = x0, y0, x1, y1 (simulated LiDAR worlds).
    """

    pose_stamp: np.ndarray | None = None  # (G,)
    pose: np.ndarray | None = None  # (G, 3)
    landmark_id: np.ndarray | None = None  # (L,) int64
    landmark_xy: np.ndarray | None = None  # (L, 2)
    world: np.ndarray | None = None  # (K, 4)
    outliers: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class Dropped:
    """One line of 'what the reader removed and why'."""

    stream: str
    count: int
    reason: str


@dataclass
class Provenance:
    path: str
    format: str
    topics: dict[str, str] = field(default_factory=dict)  # stream name -> topic/source
    dropped: list[Dropped] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass
class LogData:
    """Everything a pipeline needs from a log.

    ``bounds`` carries the noise bounds stated by the log itself (simulated logs record
    the bounds they were generated with); configs and options take precedence.
    ``other_observations`` holds observations that are not of landmarks (other robots,
    unknown barcodes): kept for the record, never mixed into the landmark problem.
    ``robots``: a log of several robots (MRCLAM ``robot="all"``) holds each robot's own log
    there; the top level then has the shared parts only (provenance, landmark truth).
    """

    provenance: Provenance
    scans: Scans | None = None
    odometry: Odometry | None = None
    observations: Observations | None = None
    other_observations: Observations | None = None
    truth: GroundTruth | None = None
    bounds: dict[str, float] = field(default_factory=dict)
    meta: dict[str, object] = field(default_factory=dict)
    robots: list[tuple[int, LogData]] | None = None  # a log of several robots: (robot number, its log)

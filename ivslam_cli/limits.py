"""Limits that bound the memory and time any input can cost.

Every allocation whose size comes from the input (a decompressed stream, a declared array
length, a message count, a map's shape) is checked against one of these limits *before* it
is made; going over is a one-line error naming the file, the limit and its value (exit 2).
The defaults keep the peak memory of reading one log under about 1.5 GB whatever the file
says, while staying far above what real logs need (the largest logs in the datasets use less
than 2 % of each). A limit can be raised (or lowered) for one process with the environment
variable ``IVSLAM_LIMIT_<NAME>`` (e.g. ``IVSLAM_LIMIT_BEAMS=500000000``), at the cost of the
memory it then allows.

============================  ==========  =====================================================
name                          default     what it bounds
============================  ==========  =====================================================
``TEXT_BYTES``                256 MiB     decompressed size of one text log or file (CARMEN,
                                          GMapping .gfs, URG, Victoria Park, each MRCLAM file,
                                          relations)
``JSON_BYTES``                64 MiB      decompressed size of a keyframe JSON log (its parsed
                                          form takes about five times that)
``LINE_BYTES``                16 MiB      one line of a text log
``BEAMS_PER_SCAN``            65536       beams of one scan
``BEAMS``                     2^27        beams of one log (ranges + valid flags: 5 bytes each)
``SCANS``                     2^22        scans of one log
``RECORDS``                   2^23        rows of one other stream (odometry, observations,
                                          truth, tf, relations)
``CHUNK_BYTES``               256 MiB     one decompressed chunk of an MCAP file or ROS 1 bag
``CELLS``                     2^28        cells of a map grid read back from a result
``MAP_CELLS``                 2^24        cells of one map a LiDAR run builds: its tiles (a
                                          lidar.eps far finer than the area mapped) and the
                                          dense grid over them (a pose far from the others)
``ROWS``                      2^26        rows of any other dataset read back from a result
``POSE_SET_BYTES``            2 GiB       the landmark CSP's pose sets: nodes × observations ×
                                          ``landmarks.pose_slices`` (fewer slices need less)
============================  ==========  =====================================================

Limits of the pipelines' own work (subpaving boxes, sweeps, pairs) are configuration keys
(``pairs.max_boxes``, ``pairs.max_work``, ``landmarks.max_iterations``, ...): see
``docs/config.md``.
"""

from __future__ import annotations

import os

from ivslam_cli.errors import IvslamError

MiB = 1 << 20

DEFAULTS: dict[str, int] = {
    "TEXT_BYTES": 256 * MiB,
    "JSON_BYTES": 64 * MiB,
    "LINE_BYTES": 16 * MiB,
    "BEAMS_PER_SCAN": 1 << 16,
    "BEAMS": 1 << 27,
    "SCANS": 1 << 22,
    "RECORDS": 1 << 23,
    "CHUNK_BYTES": 256 * MiB,
    "CELLS": 1 << 28,
    "MAP_CELLS": 1 << 24,
    "ROWS": 1 << 26,
    "POSE_SET_BYTES": 1 << 31,
}


class LimitExceeded(IvslamError):
    """An input needs more than a limit allows (a one-line error naming the file, exit 2)."""


def get(name: str) -> int:
    """The limit ``name`` (``IVSLAM_LIMIT_<NAME>`` if set to a positive integer)."""
    default = DEFAULTS[name]
    raw = os.environ.get(f"IVSLAM_LIMIT_{name}")
    if raw is None:
        return default
    try:
        value = int(raw)
    except ValueError:
        return default
    return value if value > 0 else default


def describe(name: str) -> str:
    """``"NAME = value"`` in a readable unit, for messages."""
    value = get(name)
    if name.endswith("_BYTES"):
        return f"{name} = {value / MiB:g} MiB"
    return f"{name} = {value:,}"


def check(name: str, need: int | float, what: str) -> None:
    """Raise :class:`LimitExceeded` if ``need`` is above the limit ``name``."""
    if need > get(name):
        raise LimitExceeded(f"{what}: {_fmt(need)} is more than the limit {describe(name)} "
                            f"(raise it with IVSLAM_LIMIT_{name} if the input is genuine)")


def _fmt(v: int | float) -> str:
    if isinstance(v, float) and not v.is_integer():
        return f"{v:.4g}"
    v = int(v)
    return f"{v:,}" if v < 10 ** 15 else f"{v:.3e}"

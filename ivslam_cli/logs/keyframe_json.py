"""Keyframe JSON logs (``intel_gfs.json``, ``intel_corrected_log.json``; plain, .gz or .xz).

The preprocessed form of the GMapping-processed Intel Research Lab log (repository
``xiaofeng419/SLAM-2D-LIDAR-SCAN``; datasets README §2)::

    {"map": {"<unix time>": {"x": .., "y": .., "theta": .., "range": [r_0, .., r_{n-1}]}, ...}}

One entry per laser keyframe, keyed by its absolute unix time (seconds, as a decimal string).
The keys of a JSON object carry no order: entries are sorted by their numeric stamp.

* **scans**: ``n`` ranges in metres, no angle fields; as for CARMEN ``FLASER``, a 180° field
  of view from −90° is assumed, increment π/n (n = 180, 360) or π/(n−1) (n = 181, 361). The
  laser is taken at the robot origin (in ``intel.gfs.log`` the FLASER laser pose equals its
  robot pose). The log's "no return" value is detected as in the CARMEN reader: a value that
  is the maximum of the whole log, above twice the median range and in >= 0.5 % of at least
  1000 beams (81.83 m in the Intel log) is below no valid return (``range_max`` just under it).
* **poses**: the odometry, a pose per keyframe (no twist), so ``--mode lidar`` runs on its
  increments (``lidar.motion = "pose"``). They are also kept per scan in
  ``meta["scan_odometry_pose"]`` (for ``lidar.known_poses = "scan"``). In ``intel_gfs.json``
  they are the robot's **raw odometry**; in ``intel_corrected_log.json`` the **GMapping
  corrected** trajectory (a file whose name contains "corrected" is taken as such and says so
  in its provenance). Neither is ground truth: nothing is put in ``LogData.truth``.

Entries that are not an object with finite numeric ``x``, ``y``, ``theta`` and a non-empty
list of numeric ``range`` values (``NaN``/``Infinity`` ranges are kept as invalid beams), or whose key is not a finite number, are dropped and counted; two
entries with the same stamp keep the first. A file that is not JSON, or whose top level is
not ``{"map": {...}}`` with at least one usable entry, is a one-line :class:`LogError`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import ScanSink, make_odometry
from ivslam_cli.logs.model import Dropped, LogData, Provenance
from ivslam_cli.logs.textfile import read_text

FORMAT = "keyframe-json"


def _fov(n: int) -> tuple[float, float]:
    """(angle_min, increment) of an ``n``-beam scan over 180° from −90° (the CARMEN FLASER rule)."""
    inc = math.pi / (n - 1) if n % 2 == 1 and n > 1 else math.pi / n
    return -math.pi / 2, inc


def _number(v) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _no_return_value(allr: np.ndarray) -> float | None:
    """The log's max-range 'no return' value, if it has one (see the module docstring)."""
    fin = allr[np.isfinite(allr)]
    if fin.size < 1000:
        return None
    vmax = float(fin.max())
    if vmax > 2 * float(np.median(fin)) and np.count_nonzero(fin == vmax) >= 0.005 * allr.size:
        return vmax
    return None


def is_keyframe_json(head: str) -> bool:
    """Does this text (the start of a file) look like ``{"map": {...`` ?"""
    s = head.lstrip()
    if not s.startswith("{"):
        return False
    s = s[1:].lstrip()
    return s.startswith('"map"')


def read_keyframe_json(path: Path) -> LogData:
    text = read_text(path, "JSON_BYTES")
    if not text.strip():
        raise LogError("empty file", path)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise LogError(f"not valid JSON (truncated or corrupt?): {exc.msg} at line {exc.lineno} "
                       f"column {exc.colno}", path) from None
    except RecursionError:
        raise LogError("not a keyframe JSON log (nested too deeply)", path) from None
    except ValueError as exc:  # e.g. an integer literal too long to convert
        raise LogError(f"not valid JSON ({' '.join(str(exc).split())[:120]})", path) from None
    del text
    if not isinstance(doc, dict) or not isinstance(doc.get("map"), dict):
        raise LogError('not a keyframe JSON log (expected {"map": {"<unix time>": {x, y, theta, range}}})',
                       path)
    rows: list[tuple[float, float, float, float, list]] = []
    bad = 0
    for key, entry in doc["map"].items():
        try:
            stamp = float(key)
        except ValueError:
            bad += 1
            continue
        if not math.isfinite(stamp) or not isinstance(entry, dict):
            bad += 1
            continue
        x, y, th = (_number(entry.get(k)) for k in ("x", "y", "theta"))
        r = entry.get("range")
        if x is None or y is None or th is None or not isinstance(r, list) or not r:
            bad += 1
            continue
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in r):
            bad += 1  # (a non-finite range, NaN or Infinity in the JSON, is a no-return beam)
            continue
        rows.append((stamp, x, y, th, r))
    if not rows:
        raise LogError("no usable keyframe (each needs numeric x, y, theta and a list of ranges)", path)
    dropped: list[Dropped] = []
    if bad:
        dropped.append(Dropped("records", bad, "malformed keyframes (stamp not a number, or x/y/theta/range "
                                               "missing or not numbers; dropped)"))
    rows.sort(key=lambda row: row[0])
    stamps = np.array([row[0] for row in rows])
    dup = np.concatenate([[False], stamps[1:] == stamps[:-1]])
    if dup.any():
        dropped.append(Dropped("records", int(dup.sum()), "keyframes with an already seen stamp (dropped)"))
        rows = [row for row, d in zip(rows, dup) if not d]
        stamps = stamps[~dup]
    k = len(rows)
    ranges = [np.asarray(row[4], np.float32) for row in rows]
    allr = np.concatenate(ranges)
    notes: list[str] = []
    vmax = _no_return_value(allr)
    rmax = math.inf
    if vmax is not None:
        rmax = float(np.nextafter(np.float32(vmax), np.float32(0)))
        notes.append(f"value {vmax:g} m is the log's max-range 'no return' value")
    sink = ScanSink(k)
    widths = np.array([r.size for r in ranges])
    for n in np.unique(widths):  # one block per beam count (file order restored by the sink)
        idx = np.flatnonzero(widths == n)
        amin, inc = _fov(int(n))
        sink.add(idx, stamps[idx], np.full(idx.size, amin), np.full(idx.size, inc), np.zeros(idx.size),
                 np.full(idx.size, rmax), np.stack([ranges[i] for i in idx]))
    scans = sink.finish(dropped, zero_reason="beams equal to 0 (no return, marked invalid)",
                        mount=(0.0, 0.0, 0.0), frame_id="laser")
    pose = np.array([row[1:4] for row in rows], np.float64)
    odometry = make_odometry(stamps, pose, None, dropped=dropped)
    corrected = "corrected" in Path(path).name.lower()
    what = "GMapping-corrected keyframe poses" if corrected else "raw odometry at the keyframes"
    notes.append(f"poses: {what} (from the file name; neither is ground truth)")
    notes.append("angles: 180 deg field of view from -90 deg assumed (no angle fields)")
    prov = Provenance(path=str(path), format=FORMAT, topics={"scan": "map.*.range", "odom": what},
                      dropped=dropped, notes=notes)
    meta: dict[str, object] = {
        "scan_odometry_pose": pose.tolist(),
        "angles": "180 deg field of view from -90 deg assumed",
        "poses": "corrected" if corrected else "raw odometry",
        "counts": {"keyframes": k, "dropped": bad + int(dup.sum())},
    }
    return LogData(provenance=prov, scans=scans, odometry=odometry, meta=meta)

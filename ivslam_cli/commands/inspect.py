"""``ivslam inspect LOG``: what is in a log and what ``ivslam run`` would use from it."""

from __future__ import annotations

import json

import click


def _stream(name: str, stamp, extra: dict | None = None) -> dict:
    import numpy as np

    n = int(len(stamp))
    d = {"stream": name, "count": n}
    if n:
        dur = float(stamp[-1] - stamp[0])
        d.update(start=float(stamp[0]), end=float(stamp[-1]), duration_s=dur,
                 rate_hz=(n - 1) / dur if n > 1 and dur > 0 else None)
    d.update(extra or {})
    return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in d.items()}


def _scan_clock(log) -> dict:
    """Scans repeating the previous one's ranges, and the stamps against the regular clock fitted
    to them (``lidar.scan_clock``): only where the stamps' phases concentrate (a clock is there)
    and some stamp is at least 1 ms off it."""
    from ivslam_cli.errors import IvslamError
    from ivslam_cli.slam.lidar.scan_clock import fit_clock, repeated_scans

    rep = repeated_scans(log.scans)
    out = {"repeated_scans": int(rep.sum())}
    try:
        c = fit_clock(log.scans.stamp, rep)
    except IvslamError:
        return out
    if c.concentration >= 0.5 and max(-c.spread[0], c.spread[1]) >= 1e-3:
        out.update(clock_period=c.period, stamps_off_clock=list(c.spread))
    return out


def summarize(log) -> dict:
    """A JSON-able summary of a :class:`LogData` (also used by the text output)."""
    import numpy as np

    p = log.provenance
    streams = []
    if log.scans is not None:
        beams = np.diff(log.scans.offsets)
        streams.append(_stream("scans", log.scans.stamp, {
            "beams_min": int(beams.min()), "beams_max": int(beams.max()),
            "valid_fraction": float(log.scans.valid.mean()) if log.scans.valid.size else 0.0,
            "mount": list(log.scans.mount), "frame_id": log.scans.frame_id, **_scan_clock(log)}))
    if log.odometry is not None:
        o = log.odometry
        streams.append(_stream("odometry", o.stamp, {
            "pose": o.pose is not None, "twist": o.twist is not None}))
    for name, obs in (("observations", log.observations),
                      ("other_observations", log.other_observations)):
        if obs is not None:
            streams.append(_stream(name, obs.stamp, {
                "landmarks": int(np.unique(obs.landmark_id).size)}))
    t = log.truth
    truth = {
        "poses": 0 if t is None or t.pose is None else int(len(t.pose)),
        "landmarks": 0 if t is None or t.landmark_xy is None else int(len(t.landmark_xy)),
    }
    has = {s["stream"] for s in streams}
    modes = {
        "pairs": "observations" in has,
        "landmarks": "observations" in has and "odometry" in has,
        "lidar": "scans" in has,
    }
    lidar_note = ("scans + odometry (SLAM)" if {"scans", "odometry"} <= has
                  else "scans only (mapping/scan-only)" if "scans" in has else None)
    topics = log.meta.get("topics") if isinstance(log.meta.get("topics"), dict) else None
    return {
        "path": p.path, "format": p.format,
        "topics": topics, "used": dict(p.topics), "streams": streams,
        "modes": modes, "lidar_input": lidar_note,
        "ground_truth": truth,
        "dropped": [{"stream": d.stream, "count": d.count, "reason": d.reason}
                    for d in p.dropped],
        "notes": list(p.notes),
    }


def _text(s: dict) -> str:
    out = [f"log:     {s['path']}", f"format:  {s['format']}"]
    if s["topics"]:
        out.append("topics:")
        for t, info in sorted(s["topics"].items()):
            out.append(f"  {t:40s} {info['type']:40s} {info['count']:>8d}")
    out.append("used:    " + (", ".join(f"{r}={t}" for r, t in s["used"].items()) or "-"))
    out.append("streams:")
    for st in s["streams"]:
        line = f"  {st['stream']:18s} {st['count']:>8d}"
        if st.get("duration_s") is not None:
            rate = st.get("rate_hz")
            line += f"  {st['duration_s']:10.2f} s" + (f"  {rate:8.2f} Hz" if rate else "")
        if "beams_min" in st:
            beams = (st["beams_min"] if st["beams_min"] == st["beams_max"]
                     else f"{st['beams_min']}-{st['beams_max']}")
            line += f"  beams {beams}, valid {100 * st['valid_fraction']:.1f}%"
        if "landmarks" in st:
            line += f"  ids {st['landmarks']}"
        out.append(line)
        if st.get("repeated_scans"):
            out.append(f"    {st['repeated_scans']} scan(s) repeat the previous one's ranges (the same scan read again)")
        if st.get("clock_period"):
            lo, hi = st["stamps_off_clock"]
            out.append(f"    stamps {1e3 * lo:+.1f} to {1e3 * hi:+.1f} ms off a regular {1e3 * st['clock_period']:.4f} ms "
                       "clock: if the sensor keeps it (python -m bench scan_timing), lidar.scan_clock = \"fitted\"")
    modes = [m for m, ok in s["modes"].items() if ok]
    out.append("run modes: " + (", ".join(modes) or "none"))
    if s["lidar_input"]:
        out.append(f"lidar input: {s['lidar_input']}")
    gt = s["ground_truth"]
    out.append("ground truth: " + (f"{gt['poses']} poses, {gt['landmarks']} landmarks"
                                   if gt["poses"] or gt["landmarks"] else "none"))
    if s["dropped"]:
        out.append("dropped:")
        out += [f"  {d['stream']:18s} {d['count']:>8d}  {d['reason']}" for d in s["dropped"]]
    out += [f"note: {n}" for n in s["notes"]]
    return "\n".join(out)


@click.command(name="inspect")
@click.argument("log", type=click.Path(exists=False, dir_okay=True))
@click.option("--format", "fmt", default=None, help="Force a reader (see the list below).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--robot", type=int, default=None, help="MRCLAM robot number (default 1).")
@click.option("--scan-topic", default=None, help="LaserScan topic (default: found by type).")
@click.option("--odom-topic", default=None, help="Odometry/Twist topic.")
@click.option("--landmark-topic", default=None, help="LandmarkObservations topic.")
@click.option("--truth-topic", default=None, help="Ground-truth Odometry/PoseStamped topic.")
def command(log, fmt, as_json, robot, scan_topic, odom_topic, landmark_topic, truth_topic):
    """Show what is in LOG: topics, types, counts, duration, rates, beams per
    scan, which streams `ivslam run` would use and for which mode, ground truth,
    and what the reader dropped.

    \b
    Formats: ros1, ros2, mcap, carmen, gfs, mrclam, urg, victoria, keyframe-json, ivslam-h5.
    Examples:
      ivslam inspect recording.bag
      ivslam inspect MRCLAM_Dataset6 --robot 2 --json
      ivslam inspect run.mcap --scan-topic /front/scan
    """
    from ivslam_cli.logs import check_reader_options, read_log

    data = read_log(log, fmt, scan_topic=scan_topic, odom_topic=odom_topic,
                    landmark_topic=landmark_topic, truth_topic=truth_topic, robot=robot)
    check_reader_options(data, robot=robot, scan_topic=scan_topic, odom_topic=odom_topic,
                         landmark_topic=landmark_topic, truth_topic=truth_topic)
    summary = summarize(data)
    click.echo(json.dumps(summary, indent=2) if as_json else _text(summary))

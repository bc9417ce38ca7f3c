"""Read any supported robot log into the one in-memory model (:mod:`.model`).

``read_log(path)`` detects the format from the path (and a sniff of the content for
text logs); ``fmt=`` forces a reader. Every user-caused failure (missing, truncated,
corrupt, empty, unknown format, missing topic) is a :class:`LogError` with a one-line
message naming the file.
"""

from __future__ import annotations

from pathlib import Path

from ivslam_cli.errors import IvslamError, LogError
from ivslam_cli.logs.model import LogData

FORMATS: dict[str, str] = {
    "ros1": "ROS 1 bag (.bag), via rosbags",
    "ros2": "ROS 2 bag: directory with metadata.yaml, bare .db3 or bag .mcap, via rosbags",
    "mcap": "standalone .mcap (ros2/cdr or ros1 profile), via mcap + rosbags typestore",
    "carmen": "CARMEN text log (.log, .clf, .gfs.log; plain, .gz or .xz): FLASER, "
              "ROBOTLASER1, ODOM",
    "gfs": "GMapping's own log output (.gfs: LASER_READING, ODOM, SIMULATOR_POS; its particle "
           "records are not used; plain, .gz or .xz)",
    "mrclam": "UTIAS MRCLAM directory (Barcodes.dat, RobotN_*.dat)",
    "urg": "CoreSLAM/BreezySLAM URG-04LX .dat log (wheel ticks + 683 ranges in mm)",
    "victoria": "Victoria Park graph text (ODOMETRY / LANDMARK lines)",
    "keyframe-json": "keyframe JSON {\"map\": {\"<unix time>\": {x, y, theta, range}}} (Intel "
                     "intel_gfs.json: raw odometry, intel_corrected_log.json: corrected; plain, .gz or .xz)",
    "ivslam-h5": "ivslam's own HDF5 log (.h5), as written by `ivslam simulate`",
}


def list_formats() -> dict[str, str]:
    """Format name -> one-line description (the values ``--format`` accepts)."""
    return dict(FORMATS)


#: the formats (as ``Provenance.format`` names them) the topic options apply to
TOPIC_FORMATS = ("ros1", "ros2", "mcap-ros1", "mcap-ros2")


def check_reader_options(log: LogData, *, robot: int | None = None, **topics: str | None) -> None:
    """Refuse reader options that do not apply to the log read (never ignore them silently)."""
    fmt = log.provenance.format
    if robot is not None and fmt != "mrclam":
        raise LogError(f"--robot applies to MRCLAM datasets only (this log is {fmt})", log.provenance.path)
    for name, value in topics.items():
        if value is not None and fmt not in TOPIC_FORMATS:
            raise LogError(f"--{name.replace('_', '-')} applies to ROS bags and MCAP files only "
                           f"(this log is {fmt})", log.provenance.path)


def read_log(path, fmt: str | None = None, *, scan_topic: str | None = None,
             odom_topic: str | None = None, landmark_topic: str | None = None,
             truth_topic: str | None = None, robot: int | str | None = None) -> LogData:
    """Read ``path`` (format auto-detected unless ``fmt``) into :class:`LogData`.

    Topic options apply to ROS/MCAP logs, ``robot`` to MRCLAM (default 1; ``"all"``: every
    robot, in ``LogData.robots``).
    """
    from ivslam_cli.errors import IvslamError
    from ivslam_cli.inputs import check_input

    path = check_input(path, "log", dir_ok=True, error=LogError)
    if fmt is not None and fmt not in FORMATS:
        raise LogError(f"unknown format {fmt!r} (known: {', '.join(FORMATS)})", path)
    try:
        return _read(path, fmt, scan_topic, odom_topic, landmark_topic, truth_topic, robot)
    except IvslamError as exc:
        raise exc.about(path) from None


def _read(path: Path, fmt, scan_topic, odom_topic, landmark_topic, truth_topic, robot) -> LogData:
    from ivslam_cli.logs.detect import detect_format

    if fmt is None:
        fmt = detect_format(path)
    topic_opts = dict(scan_topic=scan_topic, odom_topic=odom_topic,
                      landmark_topic=landmark_topic, truth_topic=truth_topic)
    try:
        if fmt in ("ros1", "ros2"):
            from ivslam_cli.logs.ros_bag import read_bag

            return read_bag(path, fmt, **topic_opts)
        if fmt == "mcap":
            from ivslam_cli.logs.mcap_file import read_mcap

            return read_mcap(path, **topic_opts)
        if fmt == "carmen":
            from ivslam_cli.logs.carmen import read_carmen

            return read_carmen(path)
        if fmt == "gfs":
            from ivslam_cli.logs.gfs import read_gfs

            return read_gfs(path)
        if fmt == "mrclam":
            from ivslam_cli.logs.mrclam import read_mrclam, read_mrclam_all

            if robot == "all":
                return read_mrclam_all(path)
            return read_mrclam(path, robot=1 if robot is None else robot)
        if fmt == "urg":
            from ivslam_cli.logs.urg import read_urg

            return read_urg(path)
        if fmt == "victoria":
            from ivslam_cli.logs.victoria import read_victoria

            return read_victoria(path)
        if fmt == "keyframe-json":
            from ivslam_cli.logs.keyframe_json import read_keyframe_json

            return read_keyframe_json(path)
        return _read_h5(path)
    except IvslamError:
        raise
    except (OSError, EOFError) as exc:
        raise LogError(f"cannot read: {exc.strerror or exc}", path) from None
    except MemoryError:
        raise LogError("not enough memory to read it (a size the file declares is too large?)",
                       path) from None
    except (ValueError, IndexError, KeyError, UnicodeDecodeError, OverflowError, TypeError,
            RecursionError) as exc:
        text = " ".join(str(exc).split())[:160]
        raise LogError(f"corrupt {fmt} log ({type(exc).__name__}: {text})", path) from None


def _read_h5(path: Path) -> LogData:
    try:
        from ivslam_cli.logs.ivslam_h5 import read_ivslam_h5
    except ImportError:
        raise LogError("reading ivslam HDF5 logs is not available in this build "
                       "(ivslam_cli.logs.ivslam_h5 missing)", path) from None
    return read_ivslam_h5(path)

"""Format detection from the path, plus a content sniff for text logs.

Order: directories (ROS 2 bag with ``metadata.yaml``, MRCLAM with ``Barcodes.dat``),
then extensions (``.bag``, ``.db3``, ``.mcap``, ``.h5``), then text logs (optionally
``.gz``/``.xz``) recognised by their first meaningful record keyword, or keyframe JSON by
its opening ``{"map"``.
"""

from __future__ import annotations

from pathlib import Path

from ivslam_cli.errors import LogError
from ivslam_cli.logs.textfile import first_lines

_MAGIC = {b"#ROSBAG V2.0": "ros1", b"\x89MCAP0\r\n": "mcap", b"\x89HDF\r\n\x1a\n": "ivslam-h5",
          b"SQLite format 3\x00": "ros2"}
CARMEN_KEYS = ("FLASER", "ROBOTLASER1", "ODOM", "RLASER", "PARAM", "NEFF", "SYNC",
               "TRUEPOS", "RAWLASER1")


def detect_format(path: Path) -> str:
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "ros2"
        names = {p.name for p in path.iterdir()}
        if "Barcodes.dat" in names or "Barcodes.dat.xz" in names:
            return "mrclam"
        raise LogError("directory is neither a ROS 2 bag (no metadata.yaml) nor an MRCLAM "
                       "dataset (no Barcodes.dat)", path)
    with open(path, "rb") as f:
        head = f.read(16)
    if not head:
        raise LogError("empty file", path)
    suffix = path.suffix.lower()
    for magic, fmt in _MAGIC.items():
        if head.startswith(magic):
            return fmt
    if suffix in (".bag", ".db3", ".mcap", ".h5", ".hdf5"):
        raise LogError(f"not a valid {suffix} file (bad magic bytes)", path)
    return _sniff_text(path)


def _sniff_text(path: Path) -> str:
    lines = first_lines(path, 200)
    from ivslam_cli.logs.gfs import KEYS as GFS_KEYS
    from ivslam_cli.logs.keyframe_json import is_keyframe_json

    if is_keyframe_json("".join(lines[:3])):
        return "keyframe-json"
    first = [line.split()[:1] for line in lines]
    if any(t and t[0] in GFS_KEYS for t in first):
        return "gfs"
    for line in lines:
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0] == "ODOM" and len(tok) == 5:  # GMapping's ODOM x y theta time
            return "gfs"
        if tok[0] in CARMEN_KEYS:
            return "carmen"
        if tok[0] in ("ODOMETRY", "LANDMARK", "VERTEX2", "EDGE2"):
            return "victoria"
        if len(tok) == 707 and all(t.isdigit() for t in tok[:4]):  # 24 + 683 ranges
            return "urg"
    raise LogError("unknown log format (not a bag, MCAP, HDF5, CARMEN, GMapping .gfs, URG .dat, "
                   "Victoria Park text or keyframe JSON; use --format)", path)

"""Write a :class:`LogData` as MCAP, ROS 1 bag, ROS 2 bag (sqlite3 / mcap) or ivslam HDF5.

Formats (``fmt``): ``mcap`` (standalone, ros2 profile, cdr, zstd chunks), ``ros1``
(``.bag``, lz4 chunks), ``ros2`` (bag directory, sqlite3 storage), ``ros2-mcap`` (bag
directory, mcap storage), ``h5`` (:mod:`ivslam_cli.logs.ivslam_h5`). Default from the
output name: ``.mcap`` -> mcap, ``.bag`` -> ros1, ``.h5``/``.hdf5`` -> h5, anything else
-> ros2. ROS 2 bags use rosbag2 metadata version 8 (the oldest rosbags writes).

Topics (ROS 2 type names; ROS 1 drops the ``/msg/``):

==================  =====================================  =============================
``/ivslam/meta``    ``std_msgs/msg/String``                JSON (:mod:`ivslam_cli.logs.meta`), once, latched
``/tf_static``      ``tf2_msgs/msg/TFMessage``             ``base_link`` -> ``laser`` mount, once, latched
``/scan``           ``sensor_msgs/msg/LaserScan``          one per scan, frame ``laser``
``/odom``           ``nav_msgs/msg/Odometry``              frame ``odom`` -> ``base_link``: dead-reckoned pose, measured twist
``/landmarks``      ``ivslam_msgs/msg/LandmarkObservations``  one per step (empty when nothing is seen)
``/ground_truth``   ``nav_msgs/msg/Odometry``              frame ``map`` -> ``base_link``: true pose
==================  =====================================  =============================

Every message's header stamp equals its log time. Headings are written as yaw
quaternions ``(0, 0, sin(yaw/2), cos(yaw/2))``; decoded with ``atan2`` they come back
within 1e-15 rad (not bit-identical). Every other value is written exactly (LaserScan
geometry is float32 in the message: simulated logs use float32-exact values).
The landmark message definition is embedded in every file (schemas / connection
records / bag metadata). Writes are atomic: the log is written in a fresh temporary
directory beside the output and renamed into place; an existing output is replaced only
with ``force``.
"""

from __future__ import annotations

import math

from pathlib import Path

import numpy as np

from ivslam_cli.atomic import atomic_output
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import LogData
from ivslam_cli.logs.msgdefs import LANDMARK_MSG_ROS2
from ivslam_cli.logs.typestore import typestore

FORMATS = ("mcap", "ros1", "ros2", "ros2-mcap", "h5")

T_STRING = "std_msgs/msg/String"
T_TF = "tf2_msgs/msg/TFMessage"
T_SCAN = "sensor_msgs/msg/LaserScan"
T_ODOM = "nav_msgs/msg/Odometry"
TOPICS = {  # topic -> (type, latched)
    "/ivslam/meta": (T_STRING, True),
    "/tf_static": (T_TF, True),
    "/scan": (T_SCAN, False),
    "/odom": (T_ODOM, False),
    "/landmarks": (LANDMARK_MSG_ROS2, False),
    "/ground_truth": (T_ODOM, False),
}


def format_from_path(path: str | Path) -> str:
    suffix = Path(path).suffix.lower()
    return {".mcap": "mcap", ".bag": "ros1", ".h5": "h5", ".hdf5": "h5"}.get(suffix, "ros2")


def seconds_to_ns(t: np.ndarray) -> np.ndarray:
    """Nearest integer nanoseconds (exact for stamps on a 1/512 s grid)."""
    t = np.asarray(t, dtype=np.float64)
    sec = np.floor(t)
    return sec.astype(np.int64) * 1_000_000_000 + np.round((t - sec) * 1e9).astype(np.int64)


# ---- messages ------------------------------------------------------------------------

def _quat(ts, yaw: float):
    return ts.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


def _store(ros: int):
    """The project typestore (it registers ``tf2_msgs`` for ROS 1 too)."""
    return typestore(ros)


class _Builder:
    """Builds message objects of one typestore (ROS 1 headers carry ``seq``)."""

    def __init__(self, ros: int):
        self.ros = ros
        self.ts = _store(ros)
        self.T = self.ts.types
        self.seq = 0

    def header(self, ns: int, frame: str):
        stamp = self.T["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))
        if self.ros == 1:
            self.seq += 1
            return self.T["std_msgs/msg/Header"](seq=self.seq, stamp=stamp, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def serialize(self, msg, typename: str) -> bytes:
        if self.ros == 1:
            return bytes(self.ts.serialize_ros1(msg, typename))
        return bytes(self.ts.serialize_cdr(msg, typename))

    def odometry(self, ns: int, frame: str, child: str, x: float, y: float, yaw: float,
                 v: float = 0.0, w: float = 0.0):
        T = self.T
        zero36 = np.zeros(36)
        pose = T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                             orientation=_quat(self.ts, yaw)), covariance=zero36)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=v, y=0.0, z=0.0),
                                               angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=w)),
            covariance=zero36)
        return T[T_ODOM](header=self.header(ns, frame), child_frame_id=child, pose=pose, twist=twist)


def messages(log: LogData, ros: int, meta_json: str) -> list[tuple[int, str, bytes]]:
    """``(log time ns, topic, serialized message)`` for the whole log, time-sorted."""
    b = _Builder(ros)
    T = b.T
    out: list[tuple[int, int, str, bytes]] = []
    order = {topic: i for i, topic in enumerate(TOPICS)}

    def add(ns: int, topic: str, msg) -> None:
        out.append((int(ns), order[topic], topic, b.serialize(msg, TOPICS[topic][0])))

    stamps = [s.stamp for s in (log.scans, log.odometry, log.observations) if s is not None and len(s)]
    if log.truth is not None and log.truth.pose_stamp is not None and len(log.truth.pose_stamp):
        stamps.append(log.truth.pose_stamp)
    if not stamps:
        raise IvslamError("nothing to write: the log has no stream")
    t0 = int(seconds_to_ns(np.array([min(float(s[0]) for s in stamps)]))[0])
    add(t0, "/ivslam/meta", T[T_STRING](data=meta_json))

    if log.scans is not None:
        sc = log.scans
        mx, my, myaw = sc.mount
        tf = T["geometry_msgs/msg/TransformStamped"](
            header=b.header(t0, "base_link"), child_frame_id=sc.frame_id or "laser",
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=float(mx), y=float(my), z=0.0),
                rotation=_quat(b.ts, float(myaw))))
        add(t0, "/tf_static", T[T_TF](transforms=[tf]))
        ns = seconds_to_ns(sc.stamp)
        empty = np.zeros(0, dtype=np.float32)
        tinc = (np.zeros(len(sc)) if sc.time_increment is None
                else np.where(np.isfinite(sc.time_increment), sc.time_increment, 0.0)).tolist()
        for k in range(len(sc)):
            a, z = int(sc.offsets[k]), int(sc.offsets[k + 1])
            n_beams = z - a
            scan_time = float(np.diff(sc.stamp[k:k + 2])[0]) if k + 1 < len(sc) else 0.0
            add(ns[k], "/scan", T[T_SCAN](
                header=b.header(ns[k], sc.frame_id or "laser"),
                angle_min=float(sc.angle_min[k]), angle_increment=float(sc.angle_increment[k]),
                angle_max=float(np.float32(sc.angle_min[k] + (n_beams - 1) * sc.angle_increment[k])),
                time_increment=tinc[k], scan_time=scan_time,
                range_min=float(sc.range_min[k]), range_max=float(sc.range_max[k]),
                ranges=np.ascontiguousarray(sc.ranges[a:z], dtype=np.float32), intensities=empty))

    if log.odometry is not None:
        od = log.odometry
        ns = seconds_to_ns(od.stamp)
        pose = od.pose if od.pose is not None else np.zeros((len(od), 3))
        twist = od.twist if od.twist is not None else np.zeros((len(od), 2))
        for k in range(len(od)):
            add(ns[k], "/odom", b.odometry(ns[k], "odom", "base_link", float(pose[k, 0]), float(pose[k, 1]),
                                           float(pose[k, 2]), float(twist[k, 0]), float(twist[k, 1])))

    if log.observations is not None:
        ob = log.observations
        ns = seconds_to_ns(ob.stamp)
        steps = ns
        if log.truth is not None and log.truth.pose_stamp is not None:
            steps = np.concatenate([ns, seconds_to_ns(log.truth.pose_stamp)])
        steps = np.unique(steps)
        cut = np.searchsorted(ns, steps, side="left")
        end = np.searchsorted(ns, steps, side="right")
        for s, a, z in zip(steps, cut, end):
            add(s, "/landmarks", T[LANDMARK_MSG_ROS2](
                header=b.header(s, "base_link"), id=np.ascontiguousarray(ob.landmark_id[a:z], dtype=np.int32),
                range=np.ascontiguousarray(ob.range[a:z], dtype=np.float64),
                bearing=np.ascontiguousarray(ob.bearing[a:z], dtype=np.float64)))

    if log.truth is not None and log.truth.pose is not None:
        tr = log.truth
        ns = seconds_to_ns(tr.pose_stamp)
        for k in range(ns.shape[0]):
            add(ns[k], "/ground_truth", b.odometry(ns[k], "map", "base_link", float(tr.pose[k, 0]),
                                                   float(tr.pose[k, 1]), float(tr.pose[k, 2])))
    out.sort(key=lambda m: (m[0], m[1]))
    return [(ns, topic, data) for ns, _, topic, data in out]


# ---- the formats -------------------------------------------------------------------------

def _write_mcap(path: Path, msgs, meta_json: str) -> None:
    from mcap.writer import CompressionType, Writer

    ts = typestore(2)
    with open(path, "wb") as fh:
        w = Writer(fh, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True)
        w.start(profile="ros2", library="ivslam")
        channels: dict[str, int] = {}
        for topic in dict.fromkeys(t for _, t, _ in msgs):
            typename = TOPICS[topic][0]
            schema = w.register_schema(name=typename, encoding="ros2msg",
                                       data=ts.generate_msgdef(typename, ros_version=2)[0].encode())
            channels[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=schema)
        seq: dict[str, int] = {}
        for ns, topic, data in msgs:
            seq[topic] = seq.get(topic, 0) + 1
            w.add_message(channel_id=channels[topic], log_time=ns, publish_time=ns, data=data,
                          sequence=seq[topic])
        w.add_metadata("ivslam", {"json": meta_json})
        w.finish()


def _write_ros1(path: Path, msgs) -> None:
    from rosbags.rosbag1 import Writer

    ts = _store(1)
    w = Writer(path)
    w.set_compression(Writer.CompressionFormat.LZ4)
    with w:
        conns = {}
        for topic in dict.fromkeys(t for _, t, _ in msgs):
            typename, latched = TOPICS[topic]
            conns[topic] = w.add_connection(topic, typename, typestore=ts, latching=int(latched))
        for ns, topic, data in msgs:
            w.write(conns[topic], ns, data)


def _write_ros2(path: Path, msgs, storage: str) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = typestore(2)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=8, storage_plugin=plugin) as w:
        conns = {}
        for topic in dict.fromkeys(t for _, t, _ in msgs):
            conns[topic] = w.add_connection(topic, TOPICS[topic][0], typestore=ts)
        for ns, topic, data in msgs:
            w.write(conns[topic], ns, data)
    if storage == "mcap":
        for f in sorted(path.glob("*.mcap")):
            _rewrite_mcap_with_crcs(f)


def _rewrite_mcap_with_crcs(path: Path) -> None:
    """Rewrite an MCAP file (rosbags writes one uncompressed chunk without CRCs) with the
    ``mcap`` writer: the same schemas, channels, messages and metadata records, in zstd
    chunks with chunk, data-section and summary CRCs."""
    import os

    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    tmp = path.with_name(path.name + ".crc")
    with open(path, "rb") as src, open(tmp, "wb") as dst:
        reader = make_reader(src)
        header = reader.get_header()
        summary = reader.get_summary()
        w = Writer(dst, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True)
        w.start(profile=header.profile, library="ivslam")
        schema_ids = {sid: w.register_schema(name=s.name, encoding=s.encoding, data=s.data)
                      for sid, s in sorted(summary.schemas.items())}
        channel_ids = {cid: w.register_channel(topic=c.topic, message_encoding=c.message_encoding,
                                               schema_id=schema_ids.get(c.schema_id, 0),
                                               metadata=dict(c.metadata))
                       for cid, c in sorted(summary.channels.items())}
        for _, ch, m in reader.iter_messages(log_time_order=False):
            w.add_message(channel_id=channel_ids[ch.id], log_time=m.log_time, data=m.data,
                          publish_time=m.publish_time, sequence=m.sequence)
        for md in reader.iter_metadata():
            w.add_metadata(md.name, dict(md.metadata))
        w.finish()
    os.replace(tmp, path)


def write_log(path: str | Path, log: LogData, fmt: str | None = None, force: bool = False) -> Path:
    """Write ``log`` to ``path`` in ``fmt`` (default from the name), atomically."""
    from ivslam_cli.logs.meta import encode_meta

    fmt = fmt or format_from_path(path)
    if fmt not in FORMATS:
        raise IvslamError(f"unknown format '{fmt}' (choose from {', '.join(FORMATS)})", path)
    path = Path(path)
    with atomic_output(path, force=force, kind="log") as tmp:
        if fmt == "h5":
            from ivslam_cli.logs.ivslam_h5 import write_h5_file

            write_h5_file(tmp, log)
        else:
            meta_json = encode_meta(log)
            msgs = messages(log, 1 if fmt == "ros1" else 2, meta_json)
            if fmt == "mcap":
                _write_mcap(tmp, msgs, meta_json)
            elif fmt == "ros1":
                _write_ros1(tmp, msgs)
            else:
                _write_ros2(tmp, msgs, "mcap" if fmt == "ros2-mcap" else "sqlite3")
    return path

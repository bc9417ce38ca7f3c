"""From ROS topics to the log model, whatever the container (bag, db3, MCAP).

Containers give ``(topic, msgtype, count)`` and messages; this module picks the topics
(by type unless named), turns deserialised messages into stream columns, finds the laser
mount by composing the tf chain base -> ... -> laser frame, and assembles :class:`LogData`.
Message type names are normalised to the ROS 2 form ``pkg/msg/Name``.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import ScanSink, make_observations, make_odometry
from ivslam_cli.logs.laserscan_wire import ScanBlock, decode_laserscans
from ivslam_cli.logs.model import Dropped, GroundTruth, LogData, Provenance
from ivslam_cli.logs.msgdefs import LANDMARK_MSG_ROS2
from ivslam_cli.logs.meta import META_TOPIC, decode_meta

SCAN = "sensor_msgs/msg/LaserScan"
ODOM = "nav_msgs/msg/Odometry"
TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
LANDMARKS = LANDMARK_MSG_ROS2
STRING = "std_msgs/msg/String"
KNOWN = (SCAN, ODOM, TWIST, TWIST_STAMPED, POSE_STAMPED, LANDMARKS, STRING, *TF_TYPES)


def normalize_type(name: str) -> str:
    """``pkg/Name`` (ROS 1) -> ``pkg/msg/Name``."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def _is_truth(topic: str) -> bool:
    t = topic.lower()
    return "truth" in t


def _pick(candidates: list[str], prefer: str, counts: dict[str, int]) -> str | None:
    if not candidates:
        return None
    for c in candidates:
        if c.strip("/") == prefer:
            return c
    return max(candidates, key=lambda c: counts.get(c, 0))


def choose_topics(path, topics: dict[str, tuple[str, int]], *, scan_topic=None,
                  odom_topic=None, landmark_topic=None, truth_topic=None) -> dict[str, str]:
    """Role -> topic. Named topics must exist with a usable type (else LogError)."""
    counts = {t: c for t, (_, c) in topics.items()}

    def named(topic, allowed, role):
        if topic not in topics:
            have = ", ".join(sorted(topics)) or "none"
            raise LogError(f"{role} topic {topic!r} not in log (topics: {have})", path)
        if topics[topic][0] not in allowed:
            raise LogError(f"{role} topic {topic!r} has type {topics[topic][0]}, "
                           f"expected one of {', '.join(allowed)}", path)
        return topic

    roles: dict[str, str] = {}
    of = lambda *types: [t for t, (ty, _) in topics.items() if ty in types]  # noqa: E731
    if scan_topic:
        roles["scan"] = named(scan_topic, (SCAN,), "scan")
    elif (t := _pick(of(SCAN), "scan", counts)):
        roles["scan"] = t
    if truth_topic:
        roles["truth"] = named(truth_topic, (ODOM, POSE_STAMPED), "truth")
    elif (t := _pick([x for x in of(ODOM, POSE_STAMPED) if _is_truth(x)], "ground_truth",
                     counts)):
        roles["truth"] = t
    if odom_topic:
        roles["odom"] = named(odom_topic, (ODOM, TWIST, TWIST_STAMPED), "odometry")
    else:
        for types in ((ODOM,), (TWIST_STAMPED,), (TWIST,)):
            cands = [x for x in of(*types) if x != roles.get("truth") and not _is_truth(x)]
            if (t := _pick(cands, "odom", counts)):
                roles["odom"] = t
                break
    if landmark_topic:
        roles["landmarks"] = named(landmark_topic, (LANDMARKS,), "landmark")
    elif (t := _pick(of(LANDMARKS), "landmarks", counts)):
        roles["landmarks"] = t
    for tf in of(*TF_TYPES):
        roles["tf_static" if "static" in tf else "tf"] = tf  # at most one of each used
    if topics.get(META_TOPIC, ("",))[0] == STRING:
        roles["meta"] = META_TOPIC  # what simulated logs know of their truth and bounds
    return roles


def _stamp(header) -> float:
    s = header.stamp
    return s.sec + s.nanosec * 1e-9


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


@dataclass
class StreamCollector:
    """Collects the streams of one ROS log, message by message (scans in batches)."""

    path: str
    ros: int
    fmt: str
    roles: dict[str, str]
    topics: dict[str, tuple[str, int]]
    scan_capacity: int = 1024
    dropped: list[Dropped] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def __post_init__(self):
        self.sink = ScanSink(self.scan_capacity)
        self.scan_seq = 0
        self.bad_scans = 0
        self.bad_angles = 0
        # compact columns (8 bytes a value): memory stays near the size of the data
        self.odom = array("d")  # stamp, x, y, yaw, v, omega
        self.truth = array("d")  # stamp, x, y, yaw
        self.lm_stamp = array("d")
        self.lm_id = array("q")
        self.lm_range = array("d")
        self.lm_bearing = array("d")
        self.lm_messages = 0
        self.bad_lm = 0
        self.tf: dict[str, tuple[float, str, float, float, float]] = {}  # child -> earliest
        self.meta: tuple[float, str] | None = None  # the earliest metadata record

    # -- scans: raw payloads, decoded in batches ---------------------------------
    def add_scan_payloads(self, payloads: list, log_times: np.ndarray) -> None:
        """Decode a batch of serialized LaserScans (log times in seconds).

        A scan whose beam count disagrees with its own angles (``n`` beams should span
        ``angle_max - angle_min = (n - 1) * angle_increment``; one beam of slack for drivers
        that count the span differently), or whose angles are not finite or whose increment
        is 0, is dropped and counted: its beams cannot be given an angle.
        """
        blocks, bad = decode_laserscans(payloads, self.ros)
        self.bad_scans += int(bad.size)
        for b in blocks:
            n = b.ranges.shape[1]
            with np.errstate(all="ignore"):
                span = (b.angle_max - b.angle_min) / b.angle_increment
            ok = (np.isfinite(b.angle_min) & np.isfinite(b.angle_max) & np.isfinite(b.angle_increment)
                  & (b.angle_increment != 0) & np.isfinite(span) & (np.abs(span + 1 - n) <= 1.0 + 1e-3))
            if not ok.all():
                self.bad_angles += int(np.count_nonzero(~ok))
                if not ok.any():
                    continue
                b = ScanBlock(index=b.index[ok], stamp=b.stamp[ok], angle_min=b.angle_min[ok],
                              angle_max=b.angle_max[ok], angle_increment=b.angle_increment[ok],
                              range_min=b.range_min[ok], range_max=b.range_max[ok], ranges=b.ranges[ok],
                              frame_id=b.frame_id, time_increment=b.time_increment[ok])
            stamp = np.where(b.stamp > 0, b.stamp, log_times[b.index])
            self.sink.add(self.scan_seq + b.index, stamp, b.angle_min, b.angle_increment,
                          b.range_min, b.range_max, b.ranges, b.frame_id, b.angle_max,
                          time_increment=b.time_increment)
        self.scan_seq += len(payloads)

    # -- everything else: deserialised messages -----------------------------------
    def add_message(self, role: str, msg, log_time: float) -> None:
        """One deserialised message (any order: the result does not depend on it)."""
        if role == "odom":
            limits.check("RECORDS", len(self.odom) // 6 + 1, "odometry messages")
            mtype = self.topics[self.roles["odom"]][0]
            if mtype == ODOM:
                p, tw = msg.pose.pose, msg.twist.twist
                self.odom.extend((_stamp(msg.header), p.position.x, p.position.y,
                                  _yaw(p.orientation), tw.linear.x, tw.angular.z))
                self.odom_child = msg.child_frame_id
            elif mtype == TWIST_STAMPED:
                tw = msg.twist
                self.odom.extend((_stamp(msg.header), math.nan, math.nan, math.nan,
                                  tw.linear.x, tw.angular.z))
            else:
                self.odom.extend((log_time, math.nan, math.nan, math.nan, msg.linear.x,
                                  msg.angular.z))
        elif role == "truth":
            limits.check("RECORDS", len(self.truth) // 4 + 1, "ground-truth messages")
            pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
            self.truth.extend((_stamp(msg.header), pose.position.x, pose.position.y,
                               _yaw(pose.orientation)))
        elif role == "landmarks":
            n = len(msg.id)
            if len(msg.range) != n or len(msg.bearing) != n:
                self.bad_lm += 1
                return
            limits.check("RECORDS", len(self.lm_id) + n, "landmark observations")
            self.lm_messages += 1
            self.lm_stamp.extend([_stamp(msg.header)] * n)
            self.lm_id.frombytes(np.asarray(msg.id, np.int64).tobytes())
            self.lm_range.frombytes(np.asarray(msg.range, np.float64).tobytes())
            self.lm_bearing.frombytes(np.asarray(msg.bearing, np.float64).tobytes())
        elif role == "meta":
            if self.meta is None or log_time < self.meta[0]:
                self.meta = (log_time, msg.data)
        elif role in ("tf", "tf_static"):
            for t in msg.transforms:
                child = t.child_frame_id.lstrip("/")
                old = self.tf.get(child)
                if old is None or log_time < old[0]:  # the mount is static: the first one
                    if old is None:
                        limits.check("RECORDS", len(self.tf) + 1, "tf frames")
                    tr = t.transform
                    self.tf[child] = (log_time, t.header.frame_id.lstrip("/"), tr.translation.x,
                                      tr.translation.y, _yaw(tr.rotation))

    # -- assembly ----------------------------------------------------------------
    def mount(self, laser_frame: str) -> tuple[float, float, float]:
        """Compose tf from the robot base to ``laser_frame`` (identity if unknown)."""
        laser = laser_frame.lstrip("/")
        chain = [laser]
        while chain[-1] in self.tf and len(chain) < 64:
            chain.append(self.tf[chain[-1]][1])
        bases = [getattr(self, "odom_child", "").lstrip("/"), "base_link", "base_footprint"]
        base = next((b for b in bases if b and b in chain), None)
        if base is None:
            if laser:
                self.notes.append(f"no tf from the robot base to {laser!r}: laser mount "
                                  "assumed identity")
            return (0.0, 0.0, 0.0)
        x = y = th = 0.0  # T_base_laser = T_base_a * ... * T_z_laser
        for child in reversed(chain[: chain.index(base)]):
            _, _, tx, ty, tth = self.tf[child]
            c, s = math.cos(th), math.sin(th)
            x, y, th = x + c * tx - s * ty, y + s * tx + c * ty, th + tth
        th = math.atan2(math.sin(th), math.cos(th))
        self.notes.append(f"laser mount from tf {base} -> {laser}: x={x:.4f} y={y:.4f} "
                          f"yaw={math.degrees(th):.1f} deg")
        return (x, y, th)

    def finish(self) -> LogData:
        dropped = self.dropped
        if self.bad_scans:
            dropped.append(Dropped("scans", self.bad_scans,
                                   "messages with mismatched array lengths (dropped)"))
        if self.bad_angles:
            dropped.append(Dropped("scans", self.bad_angles,
                                   "scans whose beam count disagrees with angle_min/angle_max/"
                                   "angle_increment, or with non-finite or zero angles (dropped)"))
        scans = self.sink.finish(dropped, zero_reason="beams equal to 0 (no return, marked "
                                 "invalid)", mount=(0.0, 0.0, 0.0))
        if scans is not None:
            scans.mount = self.mount(scans.frame_id)
        odometry = None
        if self.odom:
            a = np.frombuffer(self.odom, np.float64).reshape(-1, 6)
            has_pose = bool(np.isfinite(a[:, 1:4]).any())
            odometry = make_odometry(a[:, 0], a[:, 1:4] if has_pose else None, a[:, 4:6],
                                     dropped=dropped)
        truth = None
        if self.truth:
            a = np.frombuffer(self.truth, np.float64).reshape(-1, 4)
            order = np.argsort(a[:, 0], kind="stable")
            ok = np.isfinite(a[order]).all(axis=1)
            truth = GroundTruth(pose_stamp=a[order][ok, 0], pose=a[order][ok, 1:4])
        observations = None
        if self.bad_lm:
            dropped.append(Dropped("observations", self.bad_lm,
                                   "messages with mismatched array lengths (dropped)"))
        if self.lm_messages:
            observations = make_observations(
                np.frombuffer(self.lm_stamp, np.float64), np.frombuffer(self.lm_id, np.int64),
                np.frombuffer(self.lm_range, np.float64), np.frombuffer(self.lm_bearing, np.float64),
                dropped=dropped)
        if scans is None and odometry is None and observations is None:
            have = ", ".join(f"{t} ({ty})" for t, (ty, _) in sorted(self.topics.items()))
            raise LogError(f"no LaserScan, odometry or landmark messages found "
                           f"(topics: {have or 'none'})", self.path)
        prov = Provenance(path=self.path, format=self.fmt,
                          topics={r: t for r, t in self.roles.items()}, dropped=dropped,
                          notes=self.notes)
        meta = {"topics": {t: {"type": ty, "count": c} for t, (ty, c) in self.topics.items()}}
        log = LogData(provenance=prov, scans=scans, odometry=odometry,
                      observations=observations, truth=truth, meta=meta)
        if self.meta is not None:
            self._apply_meta(log)
        return log

    def _apply_meta(self, log: LogData) -> None:
        """Recover the bounds, true map and outlier masks a simulated log carries."""
        try:
            rec = decode_meta(self.meta[1])
        except ValueError as exc:
            self.notes.append(f"{META_TOPIC} ignored: {exc}")
            return
        log.bounds = dict(rec.bounds)
        log.meta.update(rec.meta)
        truth = log.truth if log.truth is not None else GroundTruth()
        if rec.landmark_id is not None:
            truth.landmark_id, truth.landmark_xy = rec.landmark_id, rec.landmark_xy
        if rec.world is not None:
            truth.world = rec.world
        truth.outliers.update(rec.outliers)
        log.truth = truth

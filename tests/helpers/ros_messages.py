"""Decoding ROS / MCAP logs from the definitions embedded in the files only (``rosbags``'
``AnyReader`` *without* our typestore, ``mcap_ros2``'s decoder), independently of the
project's readers: what a reader should produce."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ivslam_cli.logs.meta import decode_meta


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _t(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _messages(path: Path, fmt: str):
    """(topic, decoded message) in log order, from embedded definitions only."""
    if fmt == "mcap":
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory

        with open(path, "rb") as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            assert reader.get_summary().schemas  # schemas are embedded
            for _, channel, _, msg in reader.iter_decoded_messages(log_time_order=True):
                yield channel.topic, msg
    else:
        from rosbags.highlevel import AnyReader

        with AnyReader([path]) as reader:
            for conn, _, raw in reader.messages():
                yield conn.topic, reader.deserialize(raw, conn.msgtype)


def decode(path: Path, fmt: str) -> dict:
    """Arrays per stream, as a reader should produce them."""
    d: dict = {k: [] for k in ("scan", "odom", "obs", "truth")}
    for topic, m in _messages(path, fmt):
        if topic == "/ivslam/meta":
            d["meta"] = decode_meta(m.data)
        elif topic == "/tf_static":
            tf = m.transforms[0].transform
            d["mount"] = (tf.translation.x, tf.translation.y, _yaw(tf.rotation))
        elif topic == "/scan":
            d["scan"].append((_t(m.header.stamp), m.angle_min, m.angle_increment, m.range_min, m.range_max,
                              np.asarray(m.ranges, dtype=np.float32)))
        elif topic == "/odom":
            p, tw = m.pose.pose, m.twist.twist
            d["odom"].append((_t(m.header.stamp), p.position.x, p.position.y, _yaw(p.orientation),
                              tw.linear.x, tw.angular.z))
        elif topic == "/landmarks":
            for i, r, b in zip(m.id, m.range, m.bearing):
                d["obs"].append((_t(m.header.stamp), int(i), float(r), float(b)))
        elif topic == "/ground_truth":
            p = m.pose.pose
            d["truth"].append((_t(m.header.stamp), p.position.x, p.position.y, _yaw(p.orientation)))
    return d

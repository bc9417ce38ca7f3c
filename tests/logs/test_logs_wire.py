"""The numpy LaserScan decoder against rosbags' deserialisers (real and generated messages)."""

from __future__ import annotations


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.logs.laserscan_wire import decode_laserscans
from ivslam_cli.logs.typestore import typestore
from tests.helpers.hyp import examples

SCAN = "sensor_msgs/msg/LaserScan"


def _check(block, i, msg):
    assert block.stamp[i] == pytest.approx(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                                           abs=1e-9)
    assert block.frame_id == msg.header.frame_id
    for f in ("angle_min", "angle_max", "angle_increment", "range_min", "range_max"):
        assert getattr(block, f)[i] == np.float32(getattr(msg, f))
    np.testing.assert_array_equal(block.ranges[i], msg.ranges)


@pytest.mark.datasets
@pytest.mark.parametrize("rel,ros", [
    ("ros2_turtlebot4_comprobo22/macfirst_floor_take_2", 2),
    ("ros1_neato_ksoltan/left_side.bag", 1),
])
def test_real_messages_match_rosbags(datasets, rel, ros):
    from rosbags.highlevel import AnyReader

    with AnyReader([datasets / rel], default_typestore=typestore(2)) as r:
        conns = [c for c in r.connections if c.topic == "/scan"]
        raws = [raw for _, _, raw in r.messages(connections=conns)][:60]
        msgs = [r.deserialize(raw, SCAN) for raw in raws]
    blocks, bad = decode_laserscans(raws, ros)
    assert bad.size == 0 and len(blocks) == 1
    b = blocks[0]
    np.testing.assert_array_equal(b.index, np.arange(len(raws)))
    for i, m in enumerate(msgs):
        _check(b, i, m)


def _msg(store, ros, sec, nsec, frame, ranges, intens):
    T = store.types
    stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    hdr = (T["std_msgs/msg/Header"](seq=3, stamp=stamp, frame_id=frame) if ros == 1
           else T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame))
    return T[SCAN](header=hdr, angle_min=-1.5, angle_max=1.5, angle_increment=0.01,
                   time_increment=0.0, scan_time=0.1, range_min=0.05, range_max=20.0,
                   ranges=np.asarray(ranges, np.float32), intensities=np.asarray(intens, np.float32))


floats = st.floats(width=32, allow_nan=False)


@settings(max_examples=examples(ci=60))
@given(ros=st.sampled_from([1, 2]),
       scans=st.lists(st.tuples(st.integers(0, 2**31 - 1), st.integers(0, 999_999_999),
                                st.text("abc_/", max_size=9),
                                st.lists(floats, max_size=12), st.lists(floats, max_size=5)),
                      min_size=1, max_size=6))
def test_generated_messages_roundtrip(ros, scans):
    store = typestore(ros)
    ser = store.serialize_ros1 if ros == 1 else store.serialize_cdr
    msgs = [_msg(store, ros, *s) for s in scans]
    raws = [bytes(ser(m, SCAN)) for m in msgs]
    blocks, bad = decode_laserscans(raws, ros)
    assert bad.size == 0
    seen = []
    for b in blocks:
        for row, i in enumerate(b.index):
            _check(b, row, msgs[i])
            seen.append(int(i))
    assert sorted(seen) == list(range(len(msgs)))


@pytest.mark.parametrize("ros", [1, 2])
def test_wrong_lengths_are_rejected_not_read(ros):
    store = typestore(ros)
    ser = store.serialize_ros1 if ros == 1 else store.serialize_cdr
    good = bytes(ser(_msg(store, ros, 1, 2, "laser", [1.0] * 10, []), SCAN))
    short = good[:-8]
    long = good + b"\0" * 8
    blocks, bad = decode_laserscans([good, short, long, b"", good[:20]], ros)
    assert list(bad) == [1, 2, 3, 4]
    assert [list(b.index) for b in blocks] == [[0]]

"""ROS 1 ``.bag`` and ROS 2 bags (directory, bare ``.db3`` / ``.mcap``) via rosbags.

``AnyReader`` (with ``default_typestore=typestore(2)`` so that Humble bags without
embedded definitions read) lists the topics and deserialises odometry, tf, truth and
landmark messages. LaserScans skip deserialisation: their raw payloads are decoded in
batches by :mod:`laserscan_wire`. For ROS 1 the payloads are sliced straight out of the
decompressed chunks through rosbags' own index (``Reader1.indexes`` / ``chunks``), the
per-message cost of ``Reader1.messages`` being the bottleneck. Bags whose index rosbags
cannot use (assertion on non-standard index records) are re-read sequentially by
:mod:`ros1_records`. ROS 1 chunks are decompressed with a bound (:mod:`.compression`), by
ivslam and by rosbags (whose bz2/lz4 decompressors are replaced by the bounded ones).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.compression import decompress
from ivslam_cli.logs.model import LogData
from ivslam_cli.logs.ros_streams import KNOWN, StreamCollector, choose_topics, normalize_type
from ivslam_cli.logs.typestore import typestore

BATCH = 4096


def _bound_rosbags_decompressors() -> None:
    """rosbags inflates ROS 1 chunks without a bound: give it the bounded decompressors."""
    from rosbags.rosbag1 import reader as r1

    r1.decompressors.update({"bz2": lambda d: decompress("bz2", d),
                             "lz4": lambda d: decompress("lz4", d)})


def _topics(connections) -> dict[str, tuple[str, int]]:
    topics: dict[str, tuple[str, int]] = {}
    for c in connections:
        ty = normalize_type(c.msgtype)
        old = topics.get(c.topic)
        topics[c.topic] = (ty, c.msgcount + (old[1] if old else 0))
    return topics


def read_bag(path: Path, fmt: str, **opts) -> LogData:
    """Read a ROS 1 bag (``fmt='ros1'``) or a ROS 2 bag (``fmt='ros2'``)."""
    from rosbags.highlevel import AnyReader

    _bound_rosbags_decompressors()
    try:
        reader = AnyReader([path], default_typestore=typestore(2))
        reader.open()
    except limits.LimitExceeded:
        raise
    except AssertionError:
        if fmt == "ros1":
            return _read_ros1_sequential(path, **opts)
        raise LogError("corrupt bag (rosbags assertion while opening)", path) from None
    except LogError:
        raise
    except Exception as exc:
        if fmt == "ros1" and path.is_file():
            # rosbags could not use the index; the chunks may still be intact
            try:
                return _read_ros1_sequential(path, **opts)
            except LogError:
                pass
        raise LogError(f"cannot read bag: {_msg(exc)}", path) from None
    try:
        return _read_open(reader, path, fmt, **opts)
    except (LogError, limits.LimitExceeded):
        raise
    except AssertionError:
        if fmt == "ros1":
            return _read_ros1_sequential(path, **opts)
        raise LogError("corrupt bag (rosbags assertion)", path) from None
    except Exception as exc:
        raise LogError(f"corrupt bag: {_msg(exc)}", path) from None
    finally:
        try:
            reader.close()
        except Exception:  # noqa: BLE001 - closing a broken reader must not mask the error
            pass


def _msg(exc: Exception) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text[:200]


def _read_open(reader, path: Path, fmt: str, **opts) -> LogData:
    topics = _topics(reader.connections)
    roles = choose_topics(path, topics, **opts)
    ros = 1 if fmt == "ros1" else 2
    scan_topic = roles.get("scan")
    cap = topics[scan_topic][1] if scan_topic else 0
    col = StreamCollector(str(path), ros, fmt, roles, topics, scan_capacity=cap)
    role_of = {t: r for r, t in roles.items() if r != "scan"}
    if scan_topic:
        scan_conns = [c for c in reader.connections if c.topic == scan_topic]
        if ros == 1:
            _ros1_scans(reader.readers[0], scan_conns, col, path)
        else:
            payloads, times = [], []
            for _, t, raw in reader.messages(connections=scan_conns):
                payloads.append(raw)
                times.append(t)
                if len(payloads) == BATCH:
                    col.add_scan_payloads(payloads, np.asarray(times) * 1e-9)
                    payloads, times = [], []
            col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
    others = [c for c in reader.connections if c.topic in role_of
              and normalize_type(c.msgtype) in KNOWN]
    if others:
        for conn, t, raw in reader.messages(connections=others):
            col.add_message(role_of[conn.topic], reader.deserialize(raw, conn.msgtype), t * 1e-9)
    return col.finish()


def _ros1_scans(r1, conns, col: StreamCollector, path: Path) -> None:
    """Slice LaserScan payloads out of chunks via rosbags' parsed ROS 1 index."""
    import heapq

    entries = list(heapq.merge(*(r1.indexes[c.id] for c in conns)))
    unpack = struct.Struct("<I").unpack_from
    bio = r1.bio
    cur_pos, chunk = None, b""
    payloads: list = []
    times: list[int] = []
    for e in entries:
        if e.chunk_pos != cur_pos:
            if payloads:
                col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
                payloads, times = [], []
            head = r1.chunks[e.chunk_pos]
            limits.check("CHUNK_BYTES", head.datasize, "a bag chunk's compressed size")
            bio.seek(head.datapos)
            raw = bio.read(head.datasize)
            if len(raw) != head.datasize:
                raise LogError("truncated bag (chunk cut)", path)
            chunk = memoryview(head.decompressor(raw))
            cur_pos = e.chunk_pos
        off, end = e.offset, len(chunk)
        while True:  # skip connection records that may precede the message
            if off + 4 > end:
                raise LogError("corrupt bag (index points past its chunk)", path)
            (hl,) = unpack(chunk, off)
            if off + 8 + hl > end:
                raise LogError("corrupt bag (record header)", path)
            is_msg = bytes(chunk[off + 4: off + 4 + hl]).find(b"op=\x02") >= 0
            (dl,) = unpack(chunk, off + 4 + hl)
            start = off + 8 + hl
            if start + dl > end:
                raise LogError("corrupt bag (record data)", path)
            if is_msg:
                break
            off = start + dl
        payloads.append(chunk[start: start + dl])
        times.append(e.time)
    col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)


def _read_ros1_sequential(path: Path, **opts) -> LogData:
    """ROS 1 bag read without its index (see :mod:`ros1_records`)."""
    from ivslam_cli.logs.ros1_records import read_records

    conns, messages = read_records(path)
    counts: dict[int, int] = {}
    for cid, _, _ in messages:
        counts[cid] = counts.get(cid, 0) + 1
    topics: dict[str, tuple[str, int]] = {}
    for cid, c in conns.items():
        old = topics.get(c.topic)
        topics[c.topic] = (normalize_type(c.msgtype), counts.get(cid, 0) + (old[1] if old else 0))
    roles = choose_topics(path, topics, **opts)
    role_of = {t: r for r, t in roles.items()}
    scan_topic = roles.get("scan")
    col = StreamCollector(str(path), 1, "ros1", roles, topics,
                          scan_capacity=topics[scan_topic][1] if scan_topic else 0)
    col.notes.append("bag index unusable by rosbags: chunks read sequentially")
    store = typestore(1)
    payloads, times = [], []
    for cid, t, raw in messages:
        c = conns.get(cid)
        role = role_of.get(c.topic) if c else None
        if role is None:
            continue
        if role == "scan":
            payloads.append(raw)
            times.append(t)
        else:
            mtype = normalize_type(c.msgtype)
            try:
                msg = store.deserialize_ros1(raw, mtype)
            except Exception as exc:  # noqa: BLE001 - corrupt payload
                raise LogError(f"corrupt {mtype} message on {c.topic}: {_msg(exc)}",
                               path) from None
            col.add_message(role, msg, t * 1e-9)
    col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
    return col.finish()

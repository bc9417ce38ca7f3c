"""Standalone ``.mcap`` files, ros2 (CDR) or ros1 profile, via the ``mcap`` package.

The ``mcap`` reader gives the header, summary (schemas, channels, chunk indexes) and
decompresses chunks; messages are decoded with the rosbags typestores
(``typestore(2).deserialize_cdr`` / ``typestore(1).deserialize_ros1``), since rosbags'
``AnyReader`` refuses ros1-profile MCAP. For speed, the records inside each decompressed
chunk are walked with ``struct`` (opcode, u64 length, and for a Message record: u16
channel, u32 sequence, u64 log time, u64 publish time, payload) instead of building one
``Message`` object per record; LaserScan payloads go to :mod:`laserscan_wire` in
batches. Files without a summary or chunk index fall back to ``iter_messages``.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.model import LogData
from ivslam_cli.logs.ros_streams import KNOWN, StreamCollector, choose_topics, normalize_type
from ivslam_cli.logs.typestore import typestore

OP_MESSAGE = 0x05


def read_mcap(path: Path, **opts) -> LogData:
    from mcap.exceptions import McapError

    try:
        return _read(path, **opts)
    except LogError:
        raise
    except (McapError, struct.error, EOFError, ValueError, KeyError, IndexError,
            AssertionError, UnicodeDecodeError, MemoryError, OverflowError) as exc:
        text = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise LogError(f"corrupt or truncated MCAP: {text}", path) from None
    except Exception as exc:  # zstd/lz4 errors and rosbags SerdeError have no common base
        text = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise LogError(f"corrupt MCAP: {type(exc).__name__}: {text}", path) from None


def _read(path: Path, **opts) -> LogData:
    from mcap.reader import make_reader
    from mcap.records import Chunk
    from mcap.stream_reader import get_chunk_data_stream
    from mcap.data_stream import ReadDataStream

    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        ros = 1 if header.profile == "ros1" else 2
        summary = reader.get_summary()
        if summary is None or not summary.chunk_indexes:
            return _read_slow(path, reader, ros, **opts)
        channels = summary.channels
        schemas = summary.schemas
        counts = dict(summary.statistics.channel_message_counts) if summary.statistics else {}
        topics: dict[str, tuple[str, int]] = {}
        for cid, ch in channels.items():
            sch = schemas.get(ch.schema_id)
            ty = normalize_type(sch.name) if sch else "(no schema)"
            old = topics.get(ch.topic)
            topics[ch.topic] = (ty, counts.get(cid, 0) + (old[1] if old else 0))
        roles = choose_topics(path, topics, **opts)
        role_of = {t: r for r, t in roles.items()}
        scan_topic = roles.get("scan")
        col = StreamCollector(str(path), ros, f"mcap-{'ros1' if ros == 1 else 'ros2'}", roles,
                              topics, scan_capacity=topics[scan_topic][1] if scan_topic else 0)
        want = {cid: role_of[ch.topic] for cid, ch in channels.items() if ch.topic in role_of
                and topics[ch.topic][0] in KNOWN}
        store = typestore(ros)
        deser = store.deserialize_ros1 if ros == 1 else store.deserialize_cdr
        ctype = {cid: topics[ch.topic][0] for cid, ch in channels.items()}
        head = struct.Struct("<BQ").unpack_from
        msg_head = struct.Struct("<HIQQ").unpack_from
        others: list[tuple[int, str, float, bytes]] = []
        for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if not any(c in want for c in ci.message_index_offsets):
                continue
            f.seek(ci.chunk_start_offset + 1 + 8)
            stream, size = get_chunk_data_stream(Chunk.read(ReadDataStream(f)))
            data = memoryview(stream.read(size))
            pos = 0
            payloads: list = []
            times: list[int] = []
            while pos < size:
                if pos + 9 > size:
                    raise LogError("corrupt MCAP chunk (record cut)", path)
                op, length = head(data, pos)
                body = pos + 9
                if body + length > size:
                    raise LogError("corrupt MCAP chunk (record length)", path)
                if op == OP_MESSAGE:
                    if length < 22:
                        raise LogError("corrupt MCAP message record", path)
                    cid, _, log_time, _ = msg_head(data, body)
                    role = want.get(cid)
                    if role == "scan":
                        payloads.append(data[body + 22: body + length])
                        times.append(log_time)
                    elif role is not None:
                        others.append((cid, role, log_time * 1e-9,
                                       bytes(data[body + 22: body + length])))
                pos = body + length
            col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
        others.sort(key=lambda o: o[2])
        for cid, role, t, raw in others:
            col.add_message(role, deser(raw, ctype[cid]), t)
        return col.finish()


def _read_slow(path: Path, reader, ros: int, **opts) -> LogData:
    """Unindexed MCAP: one pass with ``iter_messages`` (message objects)."""
    msgs = list(reader.iter_messages(log_time_order=False))
    topics: dict[str, tuple[str, int]] = {}
    for sch, ch, _ in msgs:
        ty = normalize_type(sch.name) if sch else "(no schema)"
        topics[ch.topic] = (ty, topics.get(ch.topic, (ty, 0))[1] + 1)
    roles = choose_topics(path, topics, **opts)
    role_of = {t: r for r, t in roles.items()}
    scan_topic = roles.get("scan")
    col = StreamCollector(str(path), ros, f"mcap-{'ros1' if ros == 1 else 'ros2'}", roles,
                          topics, scan_capacity=topics[scan_topic][1] if scan_topic else 0)
    store = typestore(ros)
    deser = store.deserialize_ros1 if ros == 1 else store.deserialize_cdr
    payloads, times = [], []
    for _, ch, m in msgs:
        role = role_of.get(ch.topic)
        if role == "scan":
            payloads.append(m.data)
            times.append(m.log_time)
        elif role is not None and topics[ch.topic][0] in KNOWN:
            col.add_message(role, deser(m.data, topics[ch.topic][0]), m.log_time * 1e-9)
    col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
    return col.finish()

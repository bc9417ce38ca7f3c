"""Standalone ``.mcap`` files, ros2 (CDR) or ros1 profile, via the ``mcap`` package.

The ``mcap`` reader gives the header, summary (schemas, channels, chunk indexes) and the
records; messages are decoded with the rosbags typestores (``typestore(2).deserialize_cdr``
/ ``typestore(1).deserialize_ros1``), since rosbags' ``AnyReader`` refuses ros1-profile
MCAP. For speed, the records inside each decompressed chunk are walked with ``struct``
(opcode, u64 length, and for a Message record: u16 channel, u32 sequence, u64 log time, u64
publish time, payload) instead of building one ``Message`` object per record; LaserScan
payloads go to :mod:`laserscan_wire` in batches. Files without a summary or chunk index are
read in two streaming passes (``mcap``'s ``StreamReader``: counts, then messages).

Integrity: every CRC the file carries is checked — each chunk's (over its decompressed
records), the data section's (``DataEnd``) and the summary's (``Footer``); a mismatch is a
one-line error, the file is not used. Chunks are decompressed with a bound
(:mod:`.compression`): at most the size they declare and ``limits.CHUNK_BYTES``.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.compression import decompress
from ivslam_cli.logs.model import LogData
from ivslam_cli.logs.ros_streams import KNOWN, StreamCollector, choose_topics, normalize_type
from ivslam_cli.logs.typestore import typestore, typestore_from_schemas

OP_MESSAGE = 0x05
BATCH = 4096
_FOOTER = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, summary_crc
_MAGIC = 8


def read_mcap(path: Path, **opts) -> LogData:
    from mcap.exceptions import McapError

    try:
        return _read(path, **opts)
    except (LogError, limits.LimitExceeded):
        raise
    except (McapError, struct.error, EOFError, ValueError, KeyError, IndexError,
            AssertionError, UnicodeDecodeError, MemoryError, OverflowError) as exc:
        text = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise LogError(f"corrupt or truncated MCAP: {text}", path) from None
    except OSError:
        raise
    except Exception as exc:  # zstd/lz4 errors and rosbags SerdeError have no common base
        text = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise LogError(f"corrupt MCAP: {type(exc).__name__}: {text}", path) from None


def _check_summary_crc(f, path: Path) -> None:
    """The Footer's summary CRC (when not 0) over the summary section and the footer."""
    f.seek(0, 2)
    size = f.tell()
    if size < _MAGIC + _FOOTER + _MAGIC:
        return
    f.seek(size - _MAGIC - _FOOTER)
    raw = f.read(_FOOTER)
    if raw[0] != 0x02:
        return
    summary_start, _, summary_crc = struct.unpack_from("<QQI", raw, 9)
    if summary_crc == 0 or summary_start == 0:
        return
    end = size - _MAGIC - _FOOTER + 1 + 8 + 16
    if not _MAGIC <= summary_start <= end:
        raise LogError("corrupt MCAP: the footer's summary start is outside the file", path)
    f.seek(summary_start)
    crc, left = 0, end - summary_start
    while left > 0:
        block = f.read(min(left, 1 << 20))
        if not block:
            break
        crc = zlib.crc32(block, crc)
        left -= len(block)
    if crc != summary_crc:
        raise LogError("corrupt MCAP: the summary section fails its CRC check", path)


def _check_data_crc(f, path: Path) -> None:
    """The DataEnd record's data-section CRC (when not 0), in one streaming pass."""
    from mcap.stream_reader import CRCValidationError
    from mcap.records import DataEnd, Footer
    from mcap.stream_reader import StreamReader

    f.seek(0)
    try:
        for rec in StreamReader(f, validate_crcs=True, emit_chunks=True,
                                record_size_limit=limits.get("CHUNK_BYTES")).records:
            if isinstance(rec, (DataEnd, Footer)):
                return
    except CRCValidationError:
        raise LogError("corrupt MCAP: the data section fails its CRC check", path) from None


def _chunk_records(f, path: Path, offset: int, compressed: int, declared: int) -> memoryview:
    """The decompressed records of the chunk at ``offset``, CRC-checked."""
    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk

    limits.check("CHUNK_BYTES", compressed, "an MCAP chunk's compressed size")
    limits.check("CHUNK_BYTES", declared, "an MCAP chunk's uncompressed size")
    f.seek(offset + 1 + 8)
    chunk = Chunk.read(ReadDataStream(f))
    if chunk.uncompressed_size != declared:
        raise LogError(f"corrupt MCAP: the chunk at {offset} disagrees with its index", path)
    data = decompress(chunk.compression, chunk.data, chunk.uncompressed_size)
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise LogError(f"corrupt MCAP: the chunk at byte {offset} fails its CRC check", path)
    return memoryview(data)


def _read(path: Path, **opts) -> LogData:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        header = reader.get_header()
        ros = 1 if header.profile == "ros1" else 2
        _check_summary_crc(f, path)
        summary = reader.get_summary()
        if summary is None or not summary.chunk_indexes:
            return _read_stream(path, f, ros, **opts)
        _check_data_crc(f, path)
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
        used = {channels[cid].schema_id for cid in want}
        store = typestore_from_schemas(ros, [(normalize_type(sch.name), sch.encoding, sch.data)
                                             for sid, sch in schemas.items() if sid in used],
                                       {topics[channels[cid].topic][0] for cid in want})
        deser = store.deserialize_ros1 if ros == 1 else store.deserialize_cdr
        ctype = {cid: topics[ch.topic][0] for cid, ch in channels.items()}
        head = struct.Struct("<BQ").unpack_from
        msg_head = struct.Struct("<HIQQ").unpack_from
        for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if not any(c in want for c in ci.message_index_offsets):
                continue
            data = _chunk_records(f, path, ci.chunk_start_offset, ci.compressed_size,
                                  ci.uncompressed_size)
            size = len(data)
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
                        col.add_message(role, deser(bytes(data[body + 22: body + length]), ctype[cid]),
                                        log_time * 1e-9)
                pos = body + length
            col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
        return col.finish()


def _stream_messages(f, path: Path):
    """``(schema, channel, message)`` of an MCAP file without index, in file order; chunks
    bounded and CRC-checked (and the data section's CRC at its end)."""
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    f.seek(0)
    reader = StreamReader(f, validate_crcs=True, emit_chunks=True,
                          record_size_limit=limits.get("CHUNK_BYTES"))
    for rec in reader.records:
        inner = [rec]
        if isinstance(rec, Chunk):
            limits.check("CHUNK_BYTES", rec.uncompressed_size, "an MCAP chunk's uncompressed size")
            data = decompress(rec.compression, rec.data, rec.uncompressed_size)
            plain = Chunk(compression="", data=data, message_start_time=rec.message_start_time,
                          message_end_time=rec.message_end_time, uncompressed_crc=rec.uncompressed_crc,
                          uncompressed_size=rec.uncompressed_size)
            inner = breakup_chunk(plain, validate_crc=True)
        for r in inner:
            if isinstance(r, Schema):
                schemas[r.id] = r
            elif isinstance(r, Channel):
                channels[r.id] = r
            elif isinstance(r, Message):
                ch = channels.get(r.channel_id)
                if ch is None:
                    raise LogError("corrupt MCAP: a message on an undeclared channel", path)
                yield schemas.get(ch.schema_id), ch, r


def _read_stream(path: Path, f, ros: int, **opts) -> LogData:
    """Unindexed MCAP: a counting pass, then a reading pass (nothing kept between them)."""
    from mcap.stream_reader import CRCValidationError

    try:
        topics: dict[str, tuple[str, int]] = {}
        for sch, ch, _ in _stream_messages(f, path):
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
        for _, ch, m in _stream_messages(f, path):
            role = role_of.get(ch.topic)
            if role == "scan":
                payloads.append(m.data)
                times.append(m.log_time)
                if len(payloads) == BATCH:
                    col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
                    payloads, times = [], []
            elif role is not None and topics[ch.topic][0] in KNOWN:
                col.add_message(role, deser(m.data, topics[ch.topic][0]), m.log_time * 1e-9)
        col.add_scan_payloads(payloads, np.asarray(times, np.int64) * 1e-9)
    except CRCValidationError as exc:
        raise LogError(f"corrupt MCAP: {type(exc.record).__name__ if hasattr(exc, 'record') else 'a record'} "
                       "fails its CRC check", path) from None
    return col.finish()

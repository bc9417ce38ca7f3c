"""A small sequential reader of ROS 1 bag (v2.0) records, for bags rosbags refuses.

rosbags reads a bag through its index; some real bags (the CCNY ``demo.bag``) carry
non-standard index records and make it assert although every chunk is intact. This
reader ignores the index: it walks the top-level records (bag header, chunk,
connection, index data, chunk info), decompresses each chunk and walks the connection
and message records inside. Every length is checked against what remains, so garbage
raises :class:`LogError` instead of reading out of bounds or looping.
"""

from __future__ import annotations

import mmap
import struct
from collections.abc import Iterator
from dataclasses import dataclass

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.compression import decompress

MAGIC = b"#ROSBAG V2.0\n"
OP_MSG, OP_BAG, OP_INDEX, OP_CHUNK, OP_INFO, OP_CONN = 2, 3, 4, 5, 6, 7


@dataclass
class Conn:
    id: int
    topic: str
    msgtype: str
    msgdef: str


def _fields(buf: bytes, path) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    pos = 0
    while pos < len(buf):
        if pos + 4 > len(buf):
            raise LogError("corrupt ROS 1 record header", path)
        (n,) = struct.unpack_from("<I", buf, pos)
        field = buf[pos + 4: pos + 4 + n]
        if len(field) != n or b"=" not in field:
            raise LogError("corrupt ROS 1 record header", path)
        k, v = field.split(b"=", 1)
        out[k.decode("ascii", "replace")] = v
        pos += 4 + n
    return out


def _records(buf: bytes, start: int, path, what: str) -> Iterator[tuple[dict, int, int]]:
    """(header fields, data offset, data length) of every record in ``buf[start:]``."""
    pos, end = start, len(buf)
    while pos < end:
        if pos + 4 > end:
            raise LogError(f"truncated {what} (record header cut)", path)
        (hl,) = struct.unpack_from("<I", buf, pos)
        if pos + 8 + hl > end:
            raise LogError(f"truncated or corrupt {what} (header length {hl})", path)
        header = _fields(buf[pos + 4: pos + 4 + hl], path)
        (dl,) = struct.unpack_from("<I", buf, pos + 4 + hl)
        if header.get("op") == bytes([OP_INDEX]) and header.get("ver") == b"\1\0\0\0":
            # version-1 index entries are 12 bytes (time u64, offset u32) whatever the
            # declared length says (some writers declared 20 per entry)
            count = header.get("count", b"")
            if len(count) == 4:
                dl = 12 * struct.unpack("<I", count)[0]
        data = pos + 8 + hl
        if data + dl > end:
            raise LogError(f"truncated or corrupt {what} (data length {dl})", path)
        yield header, data, dl
        pos = data + dl


def _decompress(kind: bytes, data: bytes, size: int, path) -> bytes:
    if kind not in (b"none", b"bz2", b"lz4"):
        raise LogError(f"unknown chunk compression {kind!r}", path)
    limits.check("CHUNK_BYTES", size, "a bag chunk's uncompressed size")
    try:
        out = decompress(kind.decode(), data, None)
    except (LogError, limits.LimitExceeded):
        raise
    except Exception as exc:  # corrupt compressed stream
        raise LogError(f"corrupt chunk ({type(exc).__name__})", path) from None
    if len(out) != size:
        raise LogError("corrupt chunk (size mismatch)", path)
    return out


def read_records(path) -> tuple[dict[int, Conn], list[tuple[int, int, bytes]]]:
    """Every connection, and every message as ``(conn id, time ns, payload)``, file order."""
    with open(path, "rb") as f:
        try:  # mapped, not read: a bag may be far larger than the memory
            buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except ValueError:  # an empty file cannot be mapped
            buf = b""
    if not buf[: len(MAGIC)] == MAGIC:
        raise LogError("not a ROS 1 bag v2.0 (bad magic)", path)
    conns: dict[int, Conn] = {}
    messages: list[tuple[int, int, bytes]] = []

    def conn_record(h, off, dl, src):
        info = _fields(src[off: off + dl], path)
        try:
            cid = struct.unpack("<I", h["conn"])[0]
        except (KeyError, struct.error):
            raise LogError("corrupt connection record", path) from None
        conns.setdefault(cid, Conn(cid, h.get("topic", b"").decode("utf-8", "replace"),
                                   info.get("type", b"").decode("utf-8", "replace"),
                                   info.get("message_definition", b"").decode("utf-8",
                                                                              "replace")))

    for h, off, dl in _records(buf, len(MAGIC), path, "bag"):
        op = h.get("op", b"\0")[:1]
        op = op[0] if op else 0
        if op == OP_CONN:
            conn_record(h, off, dl, buf)
        elif op == OP_CHUNK:
            try:
                size = struct.unpack("<I", h["size"])[0]
            except (KeyError, struct.error):
                raise LogError("corrupt chunk header", path) from None
            chunk = _decompress(h.get("compression", b"none"), buf[off: off + dl], size, path)
            for ch, coff, cdl in _records(chunk, 0, path, "chunk"):
                cop = ch.get("op", b"\0")[:1]
                cop = cop[0] if cop else 0
                if cop == OP_CONN:
                    conn_record(ch, coff, cdl, chunk)
                elif cop == OP_MSG:
                    try:
                        cid = struct.unpack("<I", ch["conn"])[0]
                        sec, nsec = struct.unpack("<II", ch["time"])
                    except (KeyError, struct.error):
                        raise LogError("corrupt message record", path) from None
                    limits.check("RECORDS", len(messages) + 1, "messages in the bag")
                    messages.append((cid, sec * 1_000_000_000 + nsec,
                                     chunk[coff: coff + cdl]))
        elif op not in (OP_BAG, OP_INDEX, OP_INFO):
            raise LogError(f"corrupt bag (unknown record op {op})", path)
    return conns, messages

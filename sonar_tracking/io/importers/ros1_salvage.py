"""Messages of a ROS 1 bag whose end is missing (recorder killed: no index, a cut chunk).

``rosbags`` reads a ROS 1 bag through its index at the end of the file; a bag cut off before the
index was written (a ``.bag.active`` file, a full disk) has none. :func:`scan` walks the records
from the start instead (format 2.0: each record is ``uint32`` header length, header fields
``uint32 length + name=value``, ``uint32`` data length, data; chunks hold connection and message
records, compressed with ``none``, ``bz2`` or ``lz4``) and yields the connections and messages it
finds up to the first incomplete record, including those of an uncompressed chunk cut in the middle.
"""
from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ['Connection', 'Salvage', 'scan']

_MAGIC = b'#ROSBAG V2.0\n'
_OP_MSG, _OP_CHUNK, _OP_CONN = 0x02, 0x05, 0x07


@dataclass(frozen=True)
class Connection:
    """A connection record: id, topic, ROS 2 style type name, message definition text."""

    conn: int
    topic: str
    msgtype: str
    msgdef: str


@dataclass
class Salvage:
    """What a scan found: connections by id, and where (byte offset) the readable part ends."""

    connections: dict[int, Connection] = field(default_factory=dict)
    cut_at: int | None = None
    size: int = 0


def _fields(buf: bytes) -> dict[str, bytes]:
    out, pos = {}, 0
    while pos + 4 <= len(buf):
        (n,) = struct.unpack_from('<I', buf, pos)
        item = buf[pos + 4:pos + 4 + n]
        pos += 4 + n
        name, _, value = item.partition(b'=')
        out[name.decode('ascii', 'replace')] = value
    return out


def _records(data: bytes, start: int) -> Iterator[tuple[int, dict, bytes] | int]:
    """``(offset, header fields, data)`` of each complete record; an int offset where one is cut."""
    pos = start
    while pos < len(data):
        if pos + 4 > len(data):
            yield pos
            return
        (hlen,) = struct.unpack_from('<I', data, pos)
        if pos + 8 + hlen > len(data):
            yield pos
            return
        header = _fields(data[pos + 4:pos + 4 + hlen])
        (dlen,) = struct.unpack_from('<I', data, pos + 4 + hlen)
        body = pos + 8 + hlen
        if body + dlen > len(data):
            yield pos
            return
        yield pos, header, data[body:body + dlen]
        pos = body + dlen


def _complete(header: dict, op: int) -> bool:
    """The fields a connection or message record needs are there, with their sizes."""
    if op == _OP_CONN:
        return len(header.get('conn', b'')) == 4
    if op == _OP_MSG:
        return len(header.get('conn', b'')) == 4 and len(header.get('time', b'')) == 8
    return True


def _decompress(kind: bytes, payload: bytes) -> bytes | None:
    if kind == b'none':
        return payload
    if kind == b'bz2':
        import bz2
        return bz2.decompress(payload)
    if kind == b'lz4':
        from lz4.frame import decompress
        return decompress(payload)
    return None


def scan(path: Path, salvage: Salvage, with_messages: bool = True) -> Iterator[tuple[str, int, bytes]]:
    """Yield ``(topic, time_ns, raw ROS 1 message)`` in file order; fills ``salvage`` as it goes."""
    import mmap

    from rosbags.typesys.msg import normalize_msgtype
    with open(path, 'rb') as fh:
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise ValueError(f'{path} is not a ROS 1 bag (format 2.0)')
        data = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)  # mapped, not read: bags can be large
    salvage.size = len(data)

    def handle(header: dict, body: bytes) -> Iterator[tuple[str, int, bytes]]:
        op = header.get('op', b'\x00')[:1] or b'\x00'
        if not _complete(header, op[0]):
            return      # a damaged record (a field missing or of the wrong size): skipped
        op = op[0]
        if op == _OP_CONN:
            (cid,) = struct.unpack('<I', header['conn'])
            f = _fields(body)
            if cid not in salvage.connections:
                salvage.connections[cid] = Connection(
                    cid, header.get('topic', b'').decode('utf8', 'replace'),
                    normalize_msgtype(f.get('type', b'').decode('utf8', 'replace')),
                    f.get('message_definition', b'').decode('utf8', 'replace'))
        elif op == _OP_MSG and with_messages:
            (cid,) = struct.unpack('<I', header['conn'])
            sec, nsec = struct.unpack('<II', header['time'])
            conn = salvage.connections.get(cid)
            if conn is not None:
                yield conn.topic, sec * 1_000_000_000 + nsec, body

    for rec in _records(data, len(_MAGIC)):
        if isinstance(rec, int):
            salvage.cut_at = rec
            if rec + 4 <= len(data):   # a cut chunk: its uncompressed records before the cut still count
                (hlen,) = struct.unpack_from('<I', data, rec)
                header = _fields(data[rec + 4:rec + 4 + hlen]) if rec + 4 + hlen <= len(data) else {}
                if header.get('op', b'\x00')[:1] == bytes([_OP_CHUNK]) and header.get('compression') == b'none':
                    for inner in _records(data[rec + 8 + hlen:], 0):
                        if isinstance(inner, int):
                            break
                        yield from handle(inner[1], inner[2])
            return
        offset, header, body = rec
        if header.get('op', b'\x00')[:1] == bytes([_OP_CHUNK]):
            try:
                inner_data = _decompress(header.get('compression', b'none'), body)
            except Exception:  # noqa: BLE001 - bz2 and lz4 raise several kinds for damaged data
                salvage.cut_at = offset      # a damaged chunk: the messages before it are what is readable
                return
            if inner_data is None:
                continue
            for inner in _records(inner_data, 0):
                if isinstance(inner, int):
                    break
                yield from handle(inner[1], inner[2])
        else:
            yield from handle(header, body)

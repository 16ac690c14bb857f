"""rosbag2 files through ``rosbags``: reading, also bags whose recorder was killed.

A bag its recorder closed is read with ``rosbags.rosbag2.Reader`` (every file of a split bag, in
log-time order). A bag that was not closed (``custom_data.recorder_state`` other than ``closed``
in its metadata, no metadata at all, or a file ``rosbags`` refuses) is read from its files
directly, with a :class:`TruncatedBagWarning` saying so: MCAP files record by record, in the order
written, up to the last complete record (a cut chunk gives the messages before the cut); sqlite3
files through sqlite, which replays what its write-ahead log committed. Memory stays bounded by
one chunk (at most :data:`MAX_RECORD` bytes).
"""
from __future__ import annotations

import sqlite3
import struct
import warnings
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import BinaryIO

import yaml

from sonar_tracking.io.bags.format import MCAP_MAGIC, OPEN_TAIL, RECORDER_STATE

__all__ = ['BagTopic', 'BagMessage', 'BagState', 'McapScan', 'TruncatedBagWarning', 'MAX_RECORD', 'bag_state',
           'read_bag', 'bag_topics']

#: Largest MCAP record read into memory; a longer one is taken as damage (the file is cut there).
MAX_RECORD = 1 << 28
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_DATA_END = 1, 2, 3, 4, 5, 6, 0x0F


class TruncatedBagWarning(UserWarning):
    """The bag was not closed by its recorder, or a file was cut off; messages up to the cut were read."""


@dataclass(frozen=True)
class BagTopic:
    """A recorded topic: name, ROS type, offered QoS profiles (rosbags ``Qos`` records), and the
    message definition text the bag carries for its type ('' if none)."""

    name: str
    msgtype: str
    qos: tuple = ()
    msgdef: str = ''


@dataclass(frozen=True)
class BagMessage:
    """One recorded message: topic, log time [ns], CDR bytes."""

    topic: str
    timestamp: int
    data: bytes


@dataclass
class BagState:
    """What a bag's folder says about it before it is read."""

    path: Path
    storage: str                     # 'mcap' or 'sqlite3'
    files: list[Path]
    metadata: dict | None            # rosbag2_bagfile_information, None when missing or unreadable
    state: str | None                # custom_data.recorder_state; None for bags of other recorders
    single: bool = False             # one storage file given instead of a bag folder
    open_tail: bool = False          # that file is an MCAP file ending without a summary

    @property
    def closed(self) -> bool:
        """The recorder ended the bag (or another tool wrote it): ``rosbags`` reads it as it is."""
        wal = any(Path(f'{f}-wal').exists() for f in self.files if f.suffix == '.db3')
        return not wal and (self.single and not self.open_tail
                            or (self.metadata is not None
                                and (self.state is None or not self.state.startswith('recording'))))

    def warning(self) -> str:
        """Why this bag may end before its recording did ('' for a bag closed normally)."""
        if self.single:
            return (f'{self.path} ends without a summary (its recorder did not close it): read up to its last '
                    f'complete chunk' if self.open_tail else '')
        if self.metadata is None:
            if (self.path / 'metadata.yaml').exists():
                return (f'{self.path} has a metadata.yaml that is not rosbag2 metadata (damaged, or not UTF-8 YAML): '
                        f'reading its files up to their last complete record')
            return (f'{self.path} has no readable metadata.yaml (its recorder was killed at once, or it is not a '
                    f'rosbag2 folder): reading its files up to their last complete record')
        if self.state in (None, 'closed') and self.closed:
            return ''
        n = self.metadata.get('message_count', 0)
        t0 = self.metadata.get('starting_time', {}).get('nanoseconds_since_epoch', 0)
        dt = self.metadata.get('duration', {}).get('nanoseconds', 0)
        if self.state and self.state.startswith('recording'):
            what = 'was not closed by its recorder (killed, or power lost, or still recording)'
        elif self.state in (None, 'closed'):
            what = 'has an sqlite3 write-ahead log left by a writer that did not close it'
        else:
            what = f'ended early ({self.state})'
        return (f'{self.path} {what}: read up to the last complete chunk of each file; its metadata, rewritten at '
                f'every flush, counts {n} messages' + (f' up to {_iso(t0 + dt)}, {dt / 1e9:.2f} s after the first'
                                                       if n else ''))


def _iso(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9, timezone.utc).isoformat(timespec='milliseconds')


def bag_state(path: str | Path) -> BagState:
    """Files, metadata and recorder state of a bag folder (or of one ``.mcap`` / ``.db3`` file)."""
    path = Path(path)
    if path.is_file():
        return BagState(path, 'sqlite3' if path.suffix == '.db3' else 'mcap', [path], None, None, single=True,
                        open_tail=path.suffix == '.mcap' and _ends_open(path))
    info = None
    try:
        info = yaml.safe_load((path / 'metadata.yaml').read_bytes().decode('utf-8'))['rosbag2_bagfile_information']
        if not isinstance(info, dict):
            info = None
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError):   # ValueError: not UTF-8
        pass
    files = []
    if info is not None:
        files = [path / Path(str(p)).name for p in info.get('relative_file_paths') or []]
    # Files the metadata does not list yet (the recorder split the bag after its last flush).
    listed = set(files)
    files += sorted((p for p in path.glob('*.mcap') if p not in listed), key=_file_index)
    files += sorted((p for p in path.glob('*.db3') if p not in listed), key=_file_index)
    storage = (info or {}).get('storage_identifier') or ('sqlite3' if files and files[0].suffix == '.db3' else 'mcap')
    custom = (info or {}).get('custom_data') or {}
    state = custom.get(RECORDER_STATE) if isinstance(custom, dict) else None
    return BagState(path, storage, files, info, state)


def _ends_open(path: Path) -> bool:
    """The MCAP file ends with the open tail of a recorder that has not closed it (no summary)."""
    try:
        with open(path, 'rb') as f:
            if f.seek(0, 2) < len(OPEN_TAIL) + 8:
                return False
            f.seek(-len(OPEN_TAIL), 2)
            return f.read() == OPEN_TAIL
    except OSError:
        return False


def _file_index(p: Path) -> tuple:
    stem = p.stem.rpartition('_')[2]
    return (int(stem) if stem.isdigit() else -1, p.name)


def _reader(path: Path):
    from rosbags.rosbag2 import Reader
    return Reader(path)


def bag_topics(path: str | Path) -> list[BagTopic]:
    """Topics of a bag (from its metadata; from the files themselves when it was not closed)."""
    state = bag_state(path)
    if state.closed:
        try:
            with _reader(state.path) as reader:
                return [BagTopic(c.topic, c.msgtype, tuple(c.ext.offered_qos_profiles), c.msgdef.data or '')
                        for c in reader.connections]
        except Exception:  # noqa: BLE001 - rosbags raises several kinds for damaged files: read them directly
            pass
    topics: dict[str, BagTopic] = {}
    for file in _existing(state):
        for t in (_sqlite_topics(file).values() if file.suffix == '.db3' else _mcap_topics(file)):
            topics.setdefault(t.name, t)
    return list(topics.values())


def read_bag(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in log-time order (only ``topics`` if given); see the module docstring for
    bags that were not closed (read in the order written, with a TruncatedBagWarning)."""
    from rosbags.rosbag2 import ReaderError
    state = bag_state(path)
    reason = ''
    if state.closed:
        try:
            reader = _reader(state.path)
            reader.open()
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for damaged files: read them directly
            reason = str(exc) if isinstance(exc, (ReaderError, OSError)) else f'{type(exc).__name__}: {exc}'
        else:
            try:
                conns = [c for c in reader.connections if topics is None or c.topic in topics]
                for conn, timestamp, data in reader.messages(connections=conns):
                    yield BagMessage(conn.topic, timestamp, bytes(data))
            finally:
                reader.close()
            if state.warning():
                warnings.warn(state.warning(), TruncatedBagWarning, stacklevel=2)
            return
    files = _existing(state)
    if not files:
        from rosbags.rosbag2 import ReaderError
        raise ReaderError(f'{state.path} cannot be read ({reason or "not a rosbag2 bag"}) and holds no MCAP or '
                          f'sqlite3 file')
    warnings.warn(state.warning() or f'{state.path} cannot be read as a closed bag ({reason}): reading its files '
                  f'record by record', TruncatedBagWarning, stacklevel=2)
    wanted = None if topics is None else set(topics)
    for file in files:
        if file.suffix == '.db3':
            yield from _sqlite_messages(file, wanted)
        else:
            with open(file, 'rb') as f:
                scan = McapScan(f, file)
                for m in scan.messages():
                    if wanted is None or m.topic in wanted:
                        yield m
                if scan.problem():
                    warnings.warn(scan.problem(), TruncatedBagWarning, stacklevel=2)


def _existing(state: BagState) -> list[Path]:
    return [f for f in state.files if f.exists()]


# ---------------------------------------------------------------------- MCAP, record by record
@dataclass
class McapScan:
    """Walk an MCAP file's records from the start, stopping at the first damaged or incomplete one.

    After :meth:`messages` (or :meth:`valid_end`) has run, ``end`` is the offset just after the
    last complete data record, ``cut`` the offset of the incomplete or damaged record (None when
    the file ends properly with a DataEnd or footer record, or right after a complete record),
    ``count`` the messages found, and ``channels`` the topics (channel id -> BagTopic).
    """

    f: BinaryIO
    name: str | Path = ''
    end: int = 8
    cut: int | None = None
    reason: str = ''
    count: int = 0
    size: int = 0
    ended: bool = False
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)

    def valid_end(self) -> tuple[int, int | None]:
        """``(end, cut)`` from a walk over the records, checking each chunk's CRC."""
        for _ in self._walk(read_chunks=False, with_messages=False, check_chunks=True):
            pass
        return self.end, self.cut

    def topics(self) -> dict[int, BagTopic]:
        """The channels of the whole file (chunks are read, messages skipped)."""
        for _ in self._walk(read_chunks=True, with_messages=False):
            pass
        return self.channels

    def messages(self) -> Iterator[BagMessage]:
        """The messages, in the order written (each chunk's in log-time order)."""
        yield from self._walk(read_chunks=True, with_messages=True)

    def problem(self) -> str:
        """A sentence saying where the file was cut ('' when it ends properly)."""
        if self.cut is None:
            return ''
        return (f'{self.name} is cut off at byte {self.cut} of {self.size} ({self.reason}); read the '
                f'{self.count} messages before the cut')

    def _walk(self, read_chunks: bool, with_messages: bool, check_chunks: bool = False) -> Iterator[BagMessage]:
        f = self.f
        self.size = f.seek(0, 2)
        f.seek(0)
        if f.read(8) != MCAP_MAGIC:
            self.cut, self.end, self.reason = 0, 0, 'not an MCAP file'
            return
        pos = 8
        while True:
            f.seek(pos)
            head = f.read(9)
            if len(head) < 9:
                if head:
                    self.cut, self.reason = pos, 'an incomplete record header'
                return
            op, size = head[0], struct.unpack_from('<Q', head, 1)[0]
            body = pos + 9
            if op == 0 or (op == _OP_HEADER and pos != 8):
                self.cut, self.reason = pos, f'a record with opcode {op:#x} where data belongs'
                return
            if op in (_OP_DATA_END, _OP_FOOTER):
                self.ended = True
                return
            if body + size > self.size or size > MAX_RECORD:
                self.cut = pos
                self.reason = (f'record of {size} bytes longer than the rest of the file' if size <= MAX_RECORD
                               else f'record of {size} bytes over the {MAX_RECORD}-byte limit')
                if op == _OP_CHUNK and read_chunks and size <= MAX_RECORD:
                    f.seek(body)
                    yield from self._partial_chunk(f.read(self.size - body), with_messages)
                return
            if op in (_OP_SCHEMA, _OP_CHANNEL) or (op == _OP_MESSAGE and with_messages):
                f.seek(body)
                yield from self._records(f.read(size), op, with_messages)
            elif op == _OP_CHUNK and (read_chunks or check_chunks):
                f.seek(body)
                try:
                    inner = _chunk_records(f.read(size))
                except Exception as exc:  # noqa: BLE001 - any damage (bad lengths, decompression) ends the scan
                    self.cut, self.reason = pos, f'a damaged chunk ({exc})'
                    return
                if read_chunks:
                    yield from self._inner(inner, with_messages)
            pos = self.end = body + size

    def _inner(self, data: bytes, with_messages: bool) -> Iterator[BagMessage]:
        """The complete records of a chunk's uncompressed payload, messages in log-time order."""
        msgs = []
        pos = 0
        while pos + 9 <= len(data):
            op, size = data[pos], struct.unpack_from('<Q', data, pos + 1)[0]
            if pos + 9 + size > len(data):
                break
            for m in self._records(data[pos + 9:pos + 9 + size], op, with_messages):
                msgs.append(m)
            pos += 9 + size
        msgs.sort(key=lambda m: m.timestamp)
        yield from msgs

    def _partial_chunk(self, rec: bytes, with_messages: bool) -> Iterator[BagMessage]:
        try:
            compression, off = _string(rec, 28)
        except (struct.error, UnicodeDecodeError):
            return
        if compression == '':
            yield from self._inner(rec[off + 8:], with_messages)

    def _records(self, rec: bytes, op: int, with_messages: bool) -> Iterator[BagMessage]:
        try:
            if op == _OP_SCHEMA:       # id, name, encoding, data
                (sid,) = struct.unpack_from('<H', rec, 0)
                name, off = _string(rec, 2)
                _, off = _string(rec, off)
                (dlen,) = struct.unpack_from('<I', rec, off)
                self.schemas[sid] = (name, bytes(rec[off + 4:off + 4 + dlen]).decode('utf8', 'replace'))
            elif op == _OP_CHANNEL:
                from rosbags.rosbag2.storage_mcap import get_qos
                cid, sid = struct.unpack_from('<HH', rec, 0)
                topic, off = _string(rec, 4)
                _, off = _string(rec, off)  # message encoding
                (mlen,) = struct.unpack_from('<I', rec, off)
                try:
                    qos = tuple(get_qos(rec[off + 4:off + 4 + mlen]))
                except Exception:  # noqa: BLE001 - a damaged QoS entry should not lose the channel
                    qos = ()
                name, text = self.schemas.get(sid, ('', ''))
                self.channels[cid] = BagTopic(topic, name, qos, text)
            elif op == _OP_MESSAGE and with_messages:
                cid, _, log_time, _ = struct.unpack_from('<HIQQ', rec, 0)
                if cid in self.channels:
                    self.count += 1
                    yield BagMessage(self.channels[cid].name, log_time, bytes(rec[22:]))
        except (struct.error, UnicodeDecodeError):
            return


def _chunk_records(rec: bytes) -> bytes:
    """The uncompressed records of a complete chunk record; ValueError if its CRC (when given) differs."""
    start, end, uncompressed_size, crc = struct.unpack_from('<QQQI', rec, 0)
    compression, off = _string(rec, 28)
    (csize,) = struct.unpack_from('<Q', rec, off)
    if off + 8 + csize != len(rec):
        raise ValueError('its sizes do not add up')
    payload = rec[off + 8:]
    if compression == '':
        inner = payload
    else:
        from rosbags.rosbag2.storage_mcap import decompress
        inner = decompress(payload, compression, uncompressed_size, 0)
    if len(inner) != uncompressed_size or (crc and zlib.crc32(inner) != crc):
        raise ValueError('its size or CRC does not match its content')
    return inner


def _string(buf: bytes, off: int) -> tuple[str, int]:
    (n,) = struct.unpack_from('<I', buf, off)
    if off + 4 + n > len(buf):
        raise struct.error('string runs past its record')
    return bytes(buf[off + 4:off + 4 + n]).decode('utf8'), off + 4 + n


def _mcap_topics(file: Path) -> list[BagTopic]:
    with open(file, 'rb') as f:
        return list(McapScan(f, file).topics().values())


# ---------------------------------------------------------------------- sqlite3 through sqlite
def _sqlite(file: Path) -> sqlite3.Connection:
    # Read-only, but not immutable: sqlite replays the committed part of the write-ahead log.
    return sqlite3.connect(f'file:{file}?mode=ro', uri=True)


def _sqlite_topics(file: Path) -> dict[int, BagTopic]:
    from rosbags.rosbag2.metadata import parse_qos
    con = _sqlite(file)
    try:
        try:
            msgdefs = dict(con.execute('SELECT topic_type, encoded_message_definition FROM message_definitions'))
        except sqlite3.Error:          # schema versions before 4 have no definitions
            msgdefs = {}
        out = {}
        for tid, name, msgtype, qos in con.execute('SELECT id, name, type, offered_qos_profiles FROM topics'):
            try:
                parsed = tuple(parse_qos(qos))
            except Exception:  # noqa: BLE001 - a damaged QoS entry should not lose the topic
                parsed = ()
            out[tid] = BagTopic(name, msgtype, parsed, msgdefs.get(msgtype, ''))
        return out
    finally:
        con.close()


def _sqlite_messages(file: Path, wanted: set[str] | None) -> Iterator[BagMessage]:
    topics = _sqlite_topics(file)
    con = _sqlite(file)
    try:
        for tid, timestamp, data in con.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp'):
            topic = topics.get(tid)
            if topic is not None and (wanted is None or topic.name in wanted):
                yield BagMessage(topic.name, timestamp, bytes(data))
    finally:
        con.close()

"""Crash-safe rosbag2 writing: what was flushed survives ``kill -9``, power loss and a full disk.

:class:`BagWriter` extends the ``rosbags`` writer (same connections, CDR bytes and message
definitions) with what a recorder in the field needs:

* **MCAP** files are written chunk by chunk, each with its CRC. Every flush (a timer of the
  recorder, or a chunk reaching 1 MiB) writes the chunk, its message indexes and an *open tail*
  (a DataEnd record and a footer without summary) in one ``pwrite`` at the end of the data, then
  ``fsync``. Between
  flushes the file on disk is therefore a complete MCAP file that every reader (``rosbags``,
  ``mcap``, rosbag2) reads by scanning; the next flush overwrites the tail. Closing writes the
  summary (schemas, channels, chunk indexes, statistics) in place of the tail.
* **sqlite3** files use write-ahead logging: every flush commits and checkpoints, so the file
  holds every flushed message; a killed recorder leaves committed data, never a half transaction.
* The bag folder is built under a hidden name beside it (``.NAME.creating-PID``: reserve, first
  file, metadata) and renamed to ``NAME`` when complete, so from the moment it exists every
  reader opens it; sqlite3 files get their tables before their write-ahead log is switched on, so
  readers that ignore the log (rosbags opens them immutable) read a file killed before its first
  flush.
* ``metadata.yaml`` (rosbag2 version 9, ``ros_distro: jazzy``, as ROS 2 Jazzy writes it) is
  written when the bag is opened and rewritten atomically (temporary file, ``fsync``, rename) at
  every flush, after the flush's data is on disk, with the counts of what is on disk and
  ``custom_data.recorder_state``:
  ``recording`` until the bag is closed, then ``closed`` (or ``stopped: REASON`` when writing
  failed). Readers warn about any bag that is not ``closed``.
* A full disk (``ENOSPC``, ``EDQUOT``, or ``EFBIG`` from a file size limit) or another write error
  cuts the file back to its last complete chunk, restores the open tail there, and raises
  :class:`BagWriteError`; :meth:`BagWriter.close` then ends the bag (summary, metadata) in the
  space of a reserve file (:data:`RESERVE` bytes, made when the bag is opened, deleted then).
* ``split_size`` [bytes] / ``split_duration`` [s] start a new file (``NAME_1.mcap``, ...) when
  the current one reaches either, as rosbag2's ``--max-bag-size`` / ``--max-bag-duration`` do.

:func:`~sonar_tracking.io.bags.repair.repair` makes a bag left by a killed recorder whole for every
reader.
"""
from __future__ import annotations

import errno
import os
import shutil
import sqlite3
import struct
import zlib
from collections import defaultdict
from contextlib import suppress
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path

import yaml
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.rosbag2.storage_mcap import McapWriter, PendingChunk, write_record, write_string
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from sonar_tracking.io.bags.format import MCAP_MAGIC, OPEN_TAIL, RECORDER_STATE

__all__ = ['BagWriter', 'BagWriteError', 'FileStats', 'ROS_DISTRO', 'bag_metadata', 'write_metadata']

ROS_DISTRO = 'jazzy'
METADATA_VERSION = 9
_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
#: Bytes kept free for ending the bag after the disk filled up (summary, metadata).
RESERVE = 1 << 20
RESERVE_NAME = '.space_reserve'


class BagWriteError(RuntimeError):
    """Writing failed (disk full, file too large, I/O error); the bag keeps what was flushed before."""


def _describe(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.errno in _FULL:
        return f'{"disk full" if exc.errno != errno.EFBIG else "file size limit reached"} ({exc.strerror})'
    if isinstance(exc, sqlite3.Error) and 'full' in str(exc):
        return f'disk full ({exc})'
    return f'{type(exc).__name__}: {exc}'


@dataclass
class FileStats:
    """What one storage file holds on disk: messages per connection id and their log-time range [ns]."""

    name: str
    counts: dict[int, int] = field(default_factory=lambda: defaultdict(int))
    start: int = 2**63 - 1
    end: int = 0

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    def add(self, counts: dict[int, int], start: int, end: int) -> None:
        for cid, n in counts.items():
            self.counts[cid] += n
        if counts:
            self.start, self.end = min(self.start, start), max(self.end, end)


def _pwrite_all(fd: int, data: bytes, offset: int) -> None:
    view = memoryview(data)
    while view:
        n = os.pwrite(fd, view, offset)
        if n <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        view, offset = view[n:], offset + n


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class _Staged:
    """File-like target of the rosbags MCAP writer: records are staged in memory and reach the file
    only in :meth:`commit`, in one ``pwrite`` with the open tail behind them."""

    def __init__(self, fd: int, sync: bool) -> None:
        self.fd, self.sync = fd, sync
        self.base = 0            # file offset of the first staged byte (where the open tail starts)
        self.buf = BytesIO()

    def write(self, data) -> int:
        return self.buf.write(data)

    def tell(self) -> int:
        return self.base + self.buf.tell()

    def patch(self, offset: int, data: bytes) -> None:
        """Overwrite staged bytes at file offset ``offset``."""
        view = self.buf.getbuffer()
        try:
            view[offset - self.base:offset - self.base + len(data)] = data
        finally:
            view.release()

    def commit(self, tail: bytes = OPEN_TAIL) -> None:
        """Write the staged records and ``tail`` at the end of the committed data; on failure
        cut the file back there, restore the open tail and re-raise."""
        data = self.buf.getvalue()
        self.buf = BytesIO()
        try:
            _pwrite_all(self.fd, data + tail, self.base)
            if self.sync:
                os.fsync(self.fd)
        except OSError:
            try:
                os.ftruncate(self.fd, self.base)
                _pwrite_all(self.fd, OPEN_TAIL, self.base)
            except OSError:
                pass
            raise
        self.base += len(data)

    def close(self) -> None:
        try:
            self.commit(b'')
            os.ftruncate(self.fd, self.base)
            if self.sync:
                os.fsync(self.fd)
        finally:
            os.close(self.fd)
            self.fd = -1

    def abort(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


class _Bookkeeping:
    """What :class:`BagWriter` keeps of each storage file: its connections (added again to the next
    file after a split) and the stamp of its first message (for ``--split-duration``)."""

    added: list
    first_timestamp: int | None

    def add_connection(self, connection, offered_qos_profiles: str) -> None:
        super().add_connection(connection, offered_qos_profiles)
        self.added.append((connection, offered_qos_profiles))

    def _first(self, timestamp: int) -> None:
        if self.first_timestamp is None:
            self.first_timestamp = timestamp


class _McapFile(_Bookkeeping, McapWriter):
    """The rosbags MCAP writer, committing every chunk with an open tail behind it (see module doc)."""

    def __init__(self, path: Path, sync: bool = True) -> None:   # noqa: D107 - replaces the parent's file handling
        self.path = path
        self.bio = _Staged(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644), sync)
        self.bio.write(MCAP_MAGIC)
        rec = BytesIO()
        write_string(rec, 'ros2')
        write_string(rec, 'sonar_tracking bag_record')
        write_record(self.bio, 0x01, rec)
        # The parent's state (rosbags.rosbag2.storage_mcap.McapWriter.__init__), uncompressed chunks.
        self.schemas, self.channels, self.chunks = [], [], []
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
        self.compression, self.compressor = '', (lambda x: x)
        self.message_start_time, self.message_end_time = 2**63 - 1, 0
        self.channel_stats: dict[int, int] = {}
        self.added: list[tuple[object, str]] = []
        self.stats = FileStats(path.name)
        self.first_timestamp: int | None = None
        self.bio.commit()        # an empty but complete MCAP file from the start

    def write(self, connection, timestamp: int, data) -> None:
        self._first(timestamp)
        super().write(connection, timestamp, data)

    def close_chunk(self) -> None:
        chunk = self.chunk
        counts = {cid: len(msgs) for cid, msgs in chunk.msgs.items()}
        start = self.bio.tell()
        super().close_chunk()
        # The chunk's CRC (rosbags leaves it 0): readers then know a chunk torn by a power cut.
        self.bio.patch(start + 9 + 24, struct.pack('<I', zlib.crc32(chunk.bio.getbuffer())))
        try:
            self.bio.commit()
        except OSError:
            # The chunk is not in the file: forget its index and its messages.
            self.chunks.pop()
            for cid, n in counts.items():
                self.channel_stats[cid] -= n
            self.message_start_time, self.message_end_time = self.stats.start, self.stats.end
            raise
        self.stats.add(counts, chunk.message_start_time, chunk.message_end_time)

    def flush(self) -> None:
        """Commit the pending chunk, if it holds messages."""
        if self.chunk.msgs:
            self.close_chunk()

    def moved(self, path: Path) -> None:
        """The file was renamed (its folder moved); its descriptor still writes it."""
        self.path = path

    def size(self) -> int:
        return self.bio.tell() + self.chunk.bio.tell()

    def abort(self) -> None:
        self.bio.abort()


class _SqliteFile(_Bookkeeping, Sqlite3Writer):
    """The rosbags sqlite3 writer in WAL mode, committing and checkpointing at every flush."""

    SQLITE_SCHEMA = Sqlite3Writer.SQLITE_SCHEMA.replace("'rosbags'", f"'{ROS_DISTRO}'")

    def __init__(self, path: Path, sync: bool = True) -> None:   # noqa: D107 - replaces the parent's connection
        if path.exists():
            raise FileExistsError(errno.EEXIST, 'exists already', str(path))
        self.path = path
        self.sync = sync
        self.conn = sqlite3.connect(path)
        # The schema goes into the database file itself (rollback journal) before the write-ahead log is
        # switched on: readers that open the file immutable (rosbags) ignore the log, and would refuse a
        # file killed before its first checkpoint as one "missing tables".
        self.conn.execute('PRAGMA synchronous=FULL')
        self.conn.executescript(self.SQLITE_SCHEMA)
        self._wal()
        self.added: list[tuple[object, str]] = []
        self.stats = FileStats(path.name)
        self.pending = FileStats(path.name)
        self.pending_bytes = 0
        self.first_timestamp: int | None = None

    def _wal(self) -> None:
        self.conn.execute('PRAGMA journal_mode=WAL')
        self.conn.execute(f'PRAGMA synchronous={"FULL" if self.sync else "NORMAL"}')
        self.cursor = self.conn.cursor()

    def moved(self, path: Path) -> None:
        """The file was renamed (its folder moved) with nothing pending: connect to it there."""
        self.conn.close()
        self.path = path
        self.conn = sqlite3.connect(path)
        self._wal()

    def write(self, connection, timestamp: int, data) -> None:
        self._first(timestamp)
        try:
            super().write(connection, timestamp, data)
        except sqlite3.Error:
            self._rollback()
            raise
        self.pending.add({connection.id: 1}, timestamp, timestamp)
        self.pending_bytes += len(data)

    def _rollback(self) -> None:
        try:
            self.conn.rollback()
        except sqlite3.Error:
            pass
        self.pending = FileStats(self.path.name)
        self.pending_bytes = 0

    def flush(self) -> None:
        """Commit what was written since the last flush and copy it into the database file."""
        try:
            self.conn.commit()
        except sqlite3.Error:
            self._rollback()
            raise
        self.stats.add(self.pending.counts, self.pending.start, self.pending.end)
        self.pending = FileStats(self.path.name)
        self.pending_bytes = 0
        self.conn.execute('PRAGMA wal_checkpoint(PASSIVE)')

    def size(self) -> int:
        return self.path.stat().st_size + self.pending_bytes

    def close(self, version: int, metadata: str) -> None:
        try:
            try:
                self.flush()
            finally:
                # Everything committed is in the database file already: this empties the log and,
                # on a full disk, gives its space back.
                with suppress(sqlite3.Error):
                    self.conn.execute('PRAGMA wal_checkpoint(TRUNCATE)')
            self.cursor.execute('INSERT INTO metadata(metadata_version, metadata) VALUES(?, ?)', (version, metadata))
            self.conn.commit()
            # A rollback-journal file again: readers that open it immutable (rosbags) see everything.
            self.conn.execute('PRAGMA journal_mode=DELETE')
        finally:
            self.conn.close()

    def abort(self) -> None:
        self._rollback()
        self.conn.close()


def _raise(exc: BaseException) -> None:
    raise exc


def bag_metadata(storage: str, files: list[FileStats], topics: list[tuple[object, int]], state: str) -> dict:
    """rosbag2 metadata (version 9, as ROS 2 Jazzy writes it) of ``files``, with ``topics`` as
    ``(rosbags Connection, message count)`` pairs and ``custom_data.recorder_state = state``."""
    used = [f for f in files if f.message_count]
    start = min((f.start for f in used), default=0)
    end = max((f.end for f in used), default=0)
    return {'rosbag2_bagfile_information': {
        'version': METADATA_VERSION,
        'storage_identifier': storage,
        'duration': {'nanoseconds': end - start},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(f.message_count for f in files),
        'topics_with_message_count': [
            {'topic_metadata': {'name': c.topic, 'type': c.msgtype, 'serialization_format': c.ext.serialization_format,
                                'offered_qos_profiles': dump_qos_v9(list(c.ext.offered_qos_profiles)),
                                'type_description_hash': c.digest or ''},
             'message_count': n}
            for c, n in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [f.name for f in files],
        'files': [{'path': f.name,
                   'starting_time': {'nanoseconds_since_epoch': f.start if f.message_count else 0},
                   'duration': {'nanoseconds': f.end - f.start if f.message_count else 0},
                   'message_count': f.message_count} for f in files],
        'custom_data': {RECORDER_STATE: state},
        'ros_distro': ROS_DISTRO,
    }}


def write_metadata(bag: Path, metadata: dict, sync: bool = True) -> None:
    """``bag/metadata.yaml``, replaced atomically (a crash leaves the old or the new file, never half)."""
    tmp = bag / 'metadata.yaml.tmp'
    try:
        with open(tmp, 'w') as f:
            yaml.safe_dump(metadata, f, sort_keys=False)
            f.flush()
            if sync:
                os.fsync(f.fileno())
        os.replace(tmp, bag / 'metadata.yaml')
        if sync:
            _fsync_dir(bag)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise


class BagWriter(Writer):
    """A rosbags ``Writer`` whose bag survives crashes (see the module docstring).

    Use like the rosbags writer (``open``, ``add_connection``, ``write``, ``close``) and call
    :meth:`flush` periodically: a crash loses what was written after the last flush. ``write``,
    ``flush`` and ``add_connection`` raise :class:`BagWriteError` when the storage fails; the
    writer then refuses further messages and :meth:`close` ends the bag as well as it can.
    """

    def __init__(self, path: Path | str, storage: str = 'mcap', split_size: int = 0, split_duration: float = 0.0,
                 sync: bool = True) -> None:
        if storage not in ('mcap', 'sqlite3'):
            raise ValueError(f'storage must be mcap or sqlite3, got {storage!r}')
        super().__init__(path, version=METADATA_VERSION,
                         storage_plugin=StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3)
        self.storage_id = storage
        self.name = self.path.name          # of the bag and its files, also while it is built elsewhere
        self.split_size = int(split_size)
        self.split_duration_ns = int(split_duration * 1e9)
        self.sync = sync
        self.files: list[_McapFile | _SqliteFile] = []
        self.failed = ''
        self._written_metadata: dict | None = None

    # ------------------------------------------------------------------ rosbags Writer interface
    def open(self) -> None:
        """Create the bag folder with its space reserve, its first file and its metadata.

        The folder is built under a hidden name beside the bag (``.NAME.creating-PID``) and renamed
        to the bag's name once it is complete, so the bag folder, from the moment it exists, is a
        bag every reader opens (a process killed before the rename leaves the hidden folder only).
        """
        final = self.path
        if final.exists() or final.is_symlink():
            self._guard(_raise, FileExistsError(errno.EEXIST, 'exists already', str(final)))
        building = final.parent / f'.{final.name}.creating-{os.getpid()}'
        self._guard(building.mkdir, mode=0o755, parents=True)
        self.path = building
        try:
            try:
                with open(building / RESERVE_NAME, 'wb') as f:
                    f.write(bytes(RESERVE))
            except OSError:
                self._release_reserve()      # too little space even for that: record without it
            self._guard(self._new_file)
            self._guard(self._write_metadata, 'recording')
            if final.exists() or final.is_symlink():
                self._guard(_raise, FileExistsError(errno.EEXIST, 'exists already', str(final)))
            self._guard(os.rename, building, final)
            self.path = final
            if self.sync:
                self._guard(_fsync_dir, final.parent)
            self._guard(self.storage.moved, final / self.storage.path.name)
        except BaseException:
            self.abort()
            shutil.rmtree(building, ignore_errors=True)
            self.path = final
            raise

    def add_connection(self, topic: str, msgtype: str, **kwargs):
        """A connection (rosbags ``Writer.add_connection``); the metadata lists it from the next flush."""
        return self._guard(super().add_connection, topic, msgtype, **kwargs)

    def write(self, connection, timestamp: int, data: bytes | memoryview) -> None:
        """Write one message (kept in memory until the next flush, or until a 1 MiB chunk is full)."""
        if self.failed:
            raise BagWriteError(self.failed)
        current = self.storage
        first = current.first_timestamp
        if ((self.split_size and current.size() >= self.split_size)
                or (self.split_duration_ns and first is not None and timestamp - first >= self.split_duration_ns)):
            self._guard(self._split)
        self._guard(self.storage.write, connection, timestamp, data)

    def flush(self) -> None:
        """Put everything written so far on disk, and the metadata with it."""
        if self.failed:
            raise BagWriteError(self.failed)
        self._guard(self.storage.flush)
        self._guard(self._write_metadata, 'recording')

    def close(self) -> None:
        """End the bag: the last file's summary, and the metadata with ``recorder_state`` ``closed``
        (or ``stopped: REASON`` after a failure). Raises BagWriteError if that failed too."""
        storage, self.storage = self.storage, None
        errors = []
        self._release_reserve()
        if storage is not None:
            try:
                storage.close(self.version, self._metadata_text())
            except (OSError, sqlite3.Error) as exc:
                errors.append(_describe(exc))
        self.failed = self.failed or '; '.join(errors)
        try:
            self._write_metadata(f'stopped: {self.failed}' if self.failed else 'closed')
        except OSError as exc:
            errors.append(f'metadata not rewritten: {_describe(exc)}')
        if errors:
            raise BagWriteError('; '.join(errors))

    def abort(self) -> None:
        """Close the files without summary or metadata."""
        storage, self.storage = self.storage, None
        if storage is not None:
            storage.abort()

    # ------------------------------------------------------------------ state
    def stats(self) -> tuple[int, int, int]:
        """``(messages on disk, first, last log time [ns])``."""
        used = [f.stats for f in self.files if f.stats.message_count]
        return (sum(f.message_count for f in used), min((f.start for f in used), default=0),
                max((f.end for f in used), default=0))

    def _guard(self, fn, *args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except (OSError, sqlite3.Error) as exc:
            self.failed = self.failed or f'{getattr(self.storage, "path", self.path)}: {_describe(exc)}'
            raise BagWriteError(self.failed) from exc

    def _release_reserve(self) -> None:
        (self.path / RESERVE_NAME).unlink(missing_ok=True)

    def _new_file(self) -> None:
        cls, ext = (_McapFile, 'mcap') if self.storage_id == 'mcap' else (_SqliteFile, 'db3')
        previous = self.files[-1] if self.files else None
        self.storage = cls(self.path / f'{self.name}_{len(self.files)}.{ext}', self.sync)
        self.files.append(self.storage)
        if self.sync:
            _fsync_dir(self.path)
        types = set()
        for connection, qos in (previous.added if previous else []):
            if connection.msgtype not in types:
                types.add(connection.msgtype)
                self.storage.add_msgtype(connection)
            self.storage.add_connection(connection, qos)

    def _split(self) -> None:
        self.storage.close(self.version, self._metadata_text())
        self._new_file()
        self._write_metadata('recording')

    def _metadata(self, state: str) -> dict:
        counts: dict[int, int] = defaultdict(int)
        for f in self.files:
            for cid, n in f.stats.counts.items():
                counts[cid] += n
        return bag_metadata(self.storage_id, [f.stats for f in self.files],
                            [(c, counts[c.id]) for c in self.connections], state)

    def _metadata_text(self) -> str:
        return yaml.safe_dump(self._metadata('closed')['rosbag2_bagfile_information'], sort_keys=False)

    def _write_metadata(self, state: str) -> None:
        metadata = self._metadata(state)
        if metadata != self._written_metadata:
            write_metadata(self.path, metadata, self.sync)
            self._written_metadata = metadata

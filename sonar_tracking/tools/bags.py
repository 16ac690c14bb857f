"""rosbag2 files through ``rosbags``: reading (with salvage of cut-off MCAP files), QoS conversion.

A bag is read with ``rosbags.rosbag2.Reader``. When an MCAP file has lost its end (the recorder
was killed, the disk filled), the reader refuses it; :func:`read_bag` then scans the file from
the start, record by record, and yields every message up to the first incomplete record, with a
warning that says where the file was cut and how many messages survived.
"""
from __future__ import annotations

import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import yaml

__all__ = ['BagTopic', 'BagMessage', 'TruncatedBagWarning', 'read_bag', 'bag_topics', 'qos_from_rclpy',
           'qos_to_rclpy']

_MAGIC = b'\x89MCAP0\r\n'


class TruncatedBagWarning(UserWarning):
    """The bag's file was cut off; messages up to the cut were read."""


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


def _reader(path: Path):
    from rosbags.rosbag2 import Reader
    return Reader(path)


def bag_topics(path: str | Path) -> list[BagTopic]:
    """Topics of a bag (from its metadata, or from the MCAP channels of a cut-off file)."""
    from rosbags.rosbag2 import ReaderError
    path = Path(path)
    try:
        with _reader(path) as reader:
            return [BagTopic(c.topic, c.msgtype, tuple(c.ext.offered_qos_profiles), c.msgdef.data or '')
                    for c in reader.connections]
    except ReaderError:
        topics, _ = _salvage(path, with_messages=False)
        return list(topics.values())


def read_bag(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in log-time order (only ``topics`` if given)."""
    from rosbags.rosbag2 import ReaderError
    path = Path(path)
    try:
        reader = _reader(path)
        reader.open()
    except ReaderError as exc:
        _, messages = _salvage(path, with_messages=True, reason=str(exc))
        yield from (m for m in messages if topics is None or m.topic in topics)
        return
    try:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        for conn, timestamp, data in reader.messages(connections=conns):
            yield BagMessage(conn.topic, timestamp, bytes(data))
    finally:
        reader.close()


def _mcap_files(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    meta = path / 'metadata.yaml'
    if meta.exists():
        try:
            info = yaml.safe_load(meta.read_text())['rosbag2_bagfile_information']
            return [path / p for p in info['relative_file_paths']]
        except (KeyError, TypeError, yaml.YAMLError):
            pass
    return sorted(path.glob('*.mcap'))


def _salvage(path: Path, with_messages: bool, reason: str = '') -> tuple[dict, list[BagMessage]]:
    """Scan MCAP files record by record; stop at the first incomplete record and warn."""
    from rosbags.rosbag2.storage_mcap import get_qos
    files = _mcap_files(path)
    if not files or any(f.suffix != '.mcap' for f in files):
        from rosbags.rosbag2 import ReaderError
        raise ReaderError(f'{path} cannot be read ({reason}) and holds no MCAP file to salvage')
    schemas: dict[int, str] = {}
    channels: dict[int, BagTopic] = {}
    messages: list[BagMessage] = []
    for file in files:
        data = file.read_bytes()
        if data[:8] != _MAGIC:
            from rosbags.rosbag2 import ReaderError
            raise ReaderError(f'{file} is not an MCAP file')
        cut = _scan(data, 8, schemas, channels, messages, get_qos, with_messages)
        if cut is not None:
            warnings.warn(f'{file} is cut off: the record starting at byte {cut} is incomplete (the file ends at '
                          f'byte {len(data)}); read the {len(messages)} messages before the cut '
                          f'({reason or "no end of file"})', TruncatedBagWarning, stacklevel=3)
    messages.sort(key=lambda m: m.timestamp)
    return {c.name: c for c in channels.values()}, messages


def _scan(data: bytes, pos: int, schemas: dict, channels: dict, messages: list, get_qos, with_messages: bool,
          end: int | None = None) -> int | None:
    """Walk MCAP records from ``pos``; returns the offset of an incomplete record, or None."""
    end = len(data) if end is None else end
    while pos < end:
        if pos + 9 > end:
            return pos
        op = data[pos]
        (size,) = struct.unpack_from('<Q', data, pos + 1)
        body = pos + 9
        if body + size > end:
            if op == 0x06:  # a cut chunk: its uncompressed records up to the cut are still good
                _partial_chunk(data[body:end], schemas, channels, messages, get_qos, with_messages)
            return pos
        rec = data[body:body + size]
        if op == 0x03:  # Schema: id, name, encoding, data
            (sid,) = struct.unpack_from('<H', rec, 0)
            name, off = _string(rec, 2)
            _, off = _string(rec, off)
            (dlen,) = struct.unpack_from('<I', rec, off)
            schemas[sid] = (name, bytes(rec[off + 4:off + 4 + dlen]).decode('utf8', 'replace'))
        elif op == 0x04:  # Channel
            cid, sid = struct.unpack_from('<HH', rec, 0)
            topic, off = _string(rec, 4)
            _, off = _string(rec, off)  # message encoding
            (mlen,) = struct.unpack_from('<I', rec, off)
            meta = rec[off + 4:off + 4 + mlen]
            try:
                qos = tuple(get_qos(meta))
            except Exception:  # noqa: BLE001 - a damaged QoS entry should not lose the channel
                qos = ()
            name, text = schemas.get(sid, ('', ''))
            channels[cid] = BagTopic(topic, name, qos, text)
        elif op == 0x05 and with_messages:  # Message
            cid, _, log_time, _ = struct.unpack_from('<HIQQ', rec, 0)
            if cid in channels:
                messages.append(BagMessage(channels[cid].name, log_time, bytes(rec[22:])))
        elif op == 0x06:  # Chunk: time range, sizes, compression, records
            uncompressed_size = struct.unpack_from('<Q', rec, 16)[0]
            compression, off = _string(rec, 28)
            (csize,) = struct.unpack_from('<Q', rec, off)
            payload = rec[off + 8:off + 8 + csize]
            if compression == '':
                inner = payload
            elif compression == 'zstd':
                from rosbags.rosbag2.storage_mcap import decompress
                inner = decompress(payload, compression, uncompressed_size, 0)
            else:
                return pos
            _scan(bytes(inner), 0, schemas, channels, messages, get_qos, with_messages)
        elif op in (0x0F, 0x02):  # DataEnd, Footer: the rest is the summary
            return None
        pos = body + size
    return None


def _partial_chunk(rec: bytes, schemas: dict, channels: dict, messages: list, get_qos, with_messages: bool) -> None:
    try:
        compression, off = _string(rec, 28)
    except struct.error:
        return
    if compression == '':
        _scan(bytes(rec[off + 8:]), 0, schemas, channels, messages, get_qos, with_messages)


def _string(buf: bytes, off: int) -> tuple[str, int]:
    (n,) = struct.unpack_from('<I', buf, off)
    return buf[off + 4:off + 4 + n].decode('utf8'), off + 4 + n


def qos_from_rclpy(profile) -> 'object':
    """rosbags ``Qos`` of an rclpy ``QoSProfile`` (as offered by a publisher)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    def t(d) -> QosTime:
        ns = int(d.nanoseconds)
        return QosTime(ns // 10**9, ns % 10**9)

    def enum(cls, value):
        try:
            return cls(int(value))
        except ValueError:
            return cls.UNKNOWN

    return Qos(history=enum(QosHistory, profile.history), depth=int(profile.depth),
               reliability=enum(QosReliability, profile.reliability),
               durability=enum(QosDurability, profile.durability), deadline=t(profile.deadline),
               lifespan=t(profile.lifespan), liveliness=enum(QosLiveliness, profile.liveliness),
               liveliness_lease_duration=t(profile.liveliness_lease_duration),
               avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))


def qos_to_rclpy(qos: tuple, depth: int = 100):
    """An rclpy ``QoSProfile`` reproducing the reliability and durability a topic was offered with."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    reliable = all(q.reliability.name != 'BEST_EFFORT' for q in qos)
    transient = bool(qos) and all(q.durability.name == 'TRANSIENT_LOCAL' for q in qos)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)

"""Recordings in: ROS 1 and ROS 2 bags, Ping Viewer ``.bin`` logs, folders of polar frames.

Every reader yields :class:`Item`s in recording order: a ``ping`` (scanning sonars, a
:class:`~.sweeps.Ping`), a ``frame`` (imaging sonars and folders: values bins x beams with their
geometry) or an ``odometry`` (a ROS 2 ``nav_msgs/Odometry`` as a rosbags message). Problems that do
not stop the import (a message that cannot be decoded, a cut-off file) go to ``problems`` as
``(topic, stamp_ns, text)``.

Bag messages are recognised by their fields (:func:`classify`), so any driver package with the
fields of :mod:`.msgdefs` is read. Frame conventions are converted here, once:

* scan lines / echoes: bearing = s * (head - head_zero), s = -1 for a clockwise head;
* ``ProjectedSonarImage``: the definition's frame is z forward, x up, so y is starboard and the
  REP-103 bearing of a beam is ``atan2(-y, z)``; drivers that fill x forward, y port (z = 0) get
  ``atan2(y, x)``. Beams are sorted by bearing and, when not evenly spaced, resampled by linear
  interpolation onto the even grid from the first to the last bearing with the same beam count
  (LaserScan geometry has one increment); uneven range bins likewise.
"""
from __future__ import annotations

import math
import re
import struct
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sonar_tracking.core.sector import GeometryError, SectorGeometry

from .msgdefs import BUILTIN_DEFINITIONS, register_definitions
from .options import ImportOptions, ProjectedOptions, angle_to_rad
from .sweeps import Ping

__all__ = ['Item', 'Frame', 'Recording', 'open_recording', 'classify', 'RecordingError', 'even_grid',
           'projected_to_sector']

ROLES = ('scanline', 'echo', 'projected', 'odometry')
_IMAGE_DTYPES = {0: np.uint8, 1: np.int8, 2: np.uint16, 3: np.int16, 4: np.uint32, 5: np.int32, 6: np.uint64,
                 7: np.int64, 8: np.float32, 9: np.float64}


class RecordingError(RuntimeError):
    """The recording cannot be read at all; the text says why."""


@dataclass(eq=False)
class Frame:
    """One image of an imaging sonar: values (bins x beams, increasing bearing) and geometry."""

    stamp_ns: int
    log_ns: int
    values: np.ndarray
    geometry: SectorGeometry
    frame_id: str = ''


@dataclass(eq=False)
class Item:
    """One unit of a recording in order: ``kind`` is 'ping', 'frame' or 'odometry'."""

    kind: str
    topic: str
    log_ns: int
    payload: Any
    frame_id: str = ''


@dataclass(frozen=True)
class TopicInfo:
    """A source topic: name, type, message count, role (one of ROLES, or '' = not sonar data)."""

    name: str
    msgtype: str
    count: int
    role: str
    note: str = ''


def classify(typestore: Any, msgtype: str) -> str:
    """The role of a message type by its fields: 'scanline', 'echo', 'projected', 'odometry', 'pose'
    (a PoseStamped or PoseWithCovarianceStamped, imported only when named) or ''."""
    if msgtype not in typestore.fielddefs:
        return ''
    names = {name for name, _ in typestore.fielddefs[msgtype][1]}
    if {'beam_directions', 'ranges', 'image'} <= names:
        return 'projected'
    if {'angle', 'bins'} <= names:
        return 'scanline'
    if 'angle' in names and names & {'intensities', 'profile_data', 'data'}:
        return 'echo'
    if msgtype.endswith('/Odometry') and {'pose', 'twist'} <= names:
        return 'odometry'
    if msgtype.endswith(('/PoseStamped', '/PoseWithCovarianceStamped')) and {'header', 'pose'} <= names:
        return 'pose'
    return ''


def even_grid(values: np.ndarray, coords: np.ndarray, axis: int) -> tuple[np.ndarray, float, float]:
    """Values resampled along ``axis`` onto an even grid over ``coords`` (increasing), same count.

    Returns ``(values, first, last)``. Linear interpolation between the two nearest samples;
    integer data are rounded back to their dtype (so a coding such as dB counts is kept). When the
    coordinates are already even (within 1 % of a step) the values are returned unchanged.
    """
    n = len(coords)
    first, last = float(coords[0]), float(coords[-1])
    if n < 3:
        return values, first, last
    grid = np.linspace(first, last, n)
    step = (last - first) / (n - 1)
    if np.max(np.abs(coords - grid)) <= 0.01 * step:
        return values, first, last
    idx = np.clip(np.searchsorted(coords, grid, side='right') - 1, 0, n - 2)
    w = (grid - coords[idx]) / np.where(coords[idx + 1] > coords[idx], coords[idx + 1] - coords[idx], 1.0)
    v = np.moveaxis(np.asarray(values, dtype=np.float64), axis, 0)
    shape = (n,) + (1,) * (v.ndim - 1)
    out = v[idx] * (1.0 - w.reshape(shape)) + v[idx + 1] * w.reshape(shape)
    out = np.moveaxis(out, 0, axis)
    if np.dtype(values.dtype).kind in 'ui':
        info = np.iinfo(values.dtype)
        out = np.clip(np.rint(out), info.min, info.max).astype(values.dtype)
    else:
        out = out.astype(values.dtype)
    return out, first, last


def _bins_geometry(n: int, step: float) -> tuple[float, float]:
    """Centres of the first and last of ``n`` samples ``step`` apart, sample i covering [i, i+1) steps."""
    return 0.5 * step, (n - 0.5) * step


class Recording:
    """Base of the readers: ``kind``, ``topics()``, ``items(options)`` and ``problems``."""

    kind = ''

    def __init__(self, path: Path) -> None:
        self.path = path
        self.problems: list[tuple[str, int, str]] = []

    def topics(self) -> list[TopicInfo]:
        raise NotImplementedError

    def check(self, options: ImportOptions) -> None:
        """RecordingError now if ``items(options)`` could not import anything (before an output exists)."""

    def items(self, options: ImportOptions) -> Iterator[Item]:
        raise NotImplementedError

    def problem(self, topic: str, stamp_ns: int, text: str) -> None:
        self.problems.append((topic, int(stamp_ns), text))


# -- ROS bags --------------------------------------------------------------------------------------

class BagRecording(Recording):
    """A ROS 1 ``.bag`` or a ROS 2 bag (directory, ``.mcap`` or ``.db3``), read with rosbags."""

    def __init__(self, path: Path, ros1: bool) -> None:
        super().__init__(path)
        from rosbags.typesys import Stores, get_typestore
        self.kind = 'ros1' if ros1 else 'ros2'
        self.typestore = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_JAZZY)
        self._topics: dict[str, tuple[str, int]] = {}
        self._unknown: set[str] = set()
        self._salvage = None
        defs: dict[str, str] = {}
        if ros1:
            self._scan_ros1(defs)
        else:
            self._scan_ros2(defs)
        for text in register_definitions(self.typestore, defs):
            self.problem('', 0, text)
        register_definitions(self.typestore, BUILTIN_DEFINITIONS)
        for topic, (msgtype, _) in self._topics.items():
            if msgtype not in self.typestore.types:
                self._unknown.add(topic)

    def _scan_ros1(self, defs: dict[str, str]) -> None:
        from rosbags.rosbag1 import Reader, ReaderError

        from .ros1_salvage import Salvage, scan
        try:
            with Reader(self.path) as reader:
                for c in reader.connections:
                    defs[c.msgtype] = c.msgdef.data
                    name, count = self._topics.get(c.topic, (c.msgtype, 0))
                    self._topics[c.topic] = (name, count + c.msgcount)
            return
        except ReaderError as exc:
            reason = str(exc)
        # No index (the recorder was killed): read the records from the start.
        self._salvage = Salvage()
        try:
            for _ in scan(self.path, self._salvage, with_messages=False):
                pass
        except (ValueError, OSError, struct.error) as exc:
            raise RecordingError(f'{self.path} is not a readable ROS 1 bag ({reason}; {exc})') from exc
        for c in self._salvage.connections.values():
            defs[c.msgtype] = c.msgdef
            self._topics[c.topic] = (c.msgtype, -1)
        self._salvage_reason = reason

    def _scan_ros2(self, defs: dict[str, str]) -> None:
        from rosbags.rosbag2 import Reader, ReaderError

        from ..bags import TruncatedBagWarning, bag_topics
        try:
            with Reader(self.path) as reader:
                for c in reader.connections:
                    if c.msgdef.data:
                        defs[c.msgtype] = c.msgdef.data
                    self._topics[c.topic] = (c.msgtype, c.msgcount)
            return
        except (ReaderError, FileNotFoundError):
            pass  # a cut-off MCAP file: topics from its channels, definitions built in
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore', TruncatedBagWarning)  # items() reports the cut
                for t in bag_topics(self.path):
                    self._topics[t.name] = (t.msgtype, -1)
                    if t.msgdef:
                        defs[t.msgtype] = t.msgdef
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for a bad file
            raise RecordingError(f'{self.path} is not a readable ROS 2 bag ({exc})') from exc

    def topics(self) -> list[TopicInfo]:
        out = []
        for name, (msgtype, count) in sorted(self._topics.items()):
            if name in self._unknown:
                out.append(TopicInfo(name, msgtype, count, '', 'type unknown: no definition in the bag or built in'))
            else:
                out.append(TopicInfo(name, msgtype, count, classify(self.typestore, msgtype)))
        return out

    def _raw(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        if self._salvage is not None:
            from .ros1_salvage import Salvage, scan
            salvage, n = Salvage(), 0
            for topic, t, data in scan(self.path, salvage):
                if topic in topics:
                    n += 1
                    yield topic, t, data
            if salvage.cut_at is not None:
                self.problem('', 0, f'{self.path.name} has no index ({self._salvage_reason}) and is cut off at byte '
                                    f'{salvage.cut_at} of {salvage.size}: read the {n} messages before the cut')
            else:
                self.problem('', 0, f'{self.path.name} has no index ({self._salvage_reason}): read {n} messages '
                                    'record by record')
            return
        if self.kind == 'ros1':
            from rosbags.rosbag1 import Reader
            with Reader(self.path) as reader:
                conns = [c for c in reader.connections if c.topic in topics]
                try:
                    for c, t, data in reader.messages(connections=conns):
                        yield c.topic, t, data
                except Exception as exc:  # noqa: BLE001 - a damaged chunk ends the reading
                    self.problem('', 0, f'reading stopped at a damaged part of the bag ({exc}); '
                                        'the messages before it were imported')
            return
        from ..bags import TruncatedBagWarning, read_bag
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter('always', TruncatedBagWarning)
            for m in read_bag(self.path, topics):
                yield m.topic, m.timestamp, m.data
        for w in caught:
            self.problem('', 0, str(w.message))

    def _decode(self, data: bytes, msgtype: str) -> Any:
        if self.kind == 'ros1':
            return self.typestore.deserialize_ros1(data, msgtype)
        return self.typestore.deserialize_cdr(data, msgtype)

    def check(self, options: ImportOptions) -> None:
        self.sonar_topic(options)
        if options.odometry_topic not in ('', 'none'):
            self.odometry_topic(options)

    def sonar_topic(self, options: ImportOptions) -> TopicInfo:
        """The topic to import (``options.topic`` or the one recognised), else RecordingError."""
        infos = {t.name: t for t in self.topics()}
        if options.topic:
            t = infos.get(options.topic)
            if t is None:
                raise RecordingError(f'topic {options.topic} is not in {self.path}; it has {sorted(infos)}')
            if t.role not in ('scanline', 'echo', 'projected'):
                raise RecordingError(f'topic {t.name} [{t.msgtype}] is not a recognised sonar message '
                                     f'({t.note or "its fields are not those of a scan line, echo or "}'
                                     f'{"" if t.note else "ProjectedSonarImage"})')
            return t
        sonar = [t for t in infos.values() if t.role in ('scanline', 'echo', 'projected')]
        if not sonar:
            raise RecordingError(f'no sonar topic recognised in {self.path} (topics: '
                                 f'{", ".join(f"{t.name} [{t.msgtype}]" for t in infos.values()) or "none"})')
        if len(sonar) > 1:
            raise RecordingError(f'several sonar topics: {[t.name for t in sonar]}; choose one with --topic')
        return sonar[0]

    def odometry_topic(self, options: ImportOptions) -> str:
        """The odometry topic to import ('' = none)."""
        if options.odometry_topic == 'none':
            return ''
        odo = [t.name for t in self.topics() if t.role == 'odometry']
        if options.odometry_topic:
            poses = [t.name for t in self.topics() if t.role == 'pose']
            if options.odometry_topic not in odo + poses:
                raise RecordingError(f'odometry topic {options.odometry_topic} is not an Odometry, PoseStamped or '
                                     f'PoseWithCovarianceStamped topic of {self.path} (those are {odo + poses})')
            return options.odometry_topic
        if len(odo) > 1:
            self.problem('', 0, f'several odometry topics {odo}: none imported; choose one with --odometry-topic')
            return ''
        return odo[0] if odo else ''

    def angle_unit(self, topic: TopicInfo, options: ImportOptions) -> str:
        """The head-angle unit: the option, or guessed from the type and the first 500 angles."""
        if options.angle_unit != 'auto':
            return options.angle_unit
        if topic.role == 'scanline':
            return 'deg'
        fields = dict(self.typestore.fielddefs[topic.msgtype][1])
        if fields['angle'][1][0] not in ('float32', 'float64'):
            return 'grad'
        biggest, known = 0.0, len(self.problems)
        for i, (_, _, data) in enumerate(self._raw([topic.name])):
            try:
                biggest = max(biggest, abs(float(self._decode(data, topic.msgtype).angle)))
            except Exception:  # noqa: BLE001 - bad messages are reported by items()
                pass
            if i >= 500:
                break
        del self.problems[known:]  # the import reads these messages again and reports their problems then
        return 'grad' if biggest > 2 * math.pi + 0.01 else 'rad'

    def items(self, options: ImportOptions) -> Iterator[Item]:
        topic = self.sonar_topic(options)
        odo = self.odometry_topic(options)
        unit = self.angle_unit(topic, options) if topic.role != 'projected' else 'rad'
        convert = {'scanline': self._scanline, 'echo': self._echo, 'projected': self._projected}[topic.role]
        last_frame = [0]
        for name, log_ns, data in self._raw([topic.name] + ([odo] if odo else [])):
            msgtype = self._topics[name][0]
            try:
                msg = self._decode(data, msgtype)
            except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for bad bytes
                self.problem(name, log_ns, f'message cannot be decoded as {msgtype} ({exc}); skipped')
                continue
            if name == odo:
                yield Item('odometry', name, log_ns, msg)
                continue
            stamp = _stamp_ns(msg, log_ns)
            frame_id = str(getattr(msg.header, 'frame_id', ''))
            try:
                payload = convert(msg, stamp, log_ns, unit, options, last_frame)
            except (ValueError, GeometryError, IndexError) as exc:
                self.problem(name, stamp, f'{exc}; message skipped')
                continue
            if payload is not None:
                yield Item('frame' if topic.role == 'projected' else 'ping', name, log_ns, payload, frame_id)

    # -- message conversions -----------------------------------------------------------------------

    @staticmethod
    def _bearing(head: float, unit: str, options: ImportOptions) -> float:
        rad = angle_to_rad(head, unit) - math.radians(options.head_zero_deg)
        return math.remainder(-rad if options.head_clockwise else rad, 2 * math.pi)

    def _scanline(self, msg: Any, stamp: int, log_ns: int, unit: str, options: ImportOptions, _) -> Ping:
        bins = list(msg.bins)
        if not bins:
            raise ValueError('scan line has no bins')
        samples = np.array([int(b.intensity) for b in bins], dtype=np.uint8)
        dist = np.array([float(getattr(b, 'distance', 0.0)) for b in bins])
        n = len(bins)
        if n > 1 and np.all(np.isfinite(dist)) and np.all(np.diff(dist) > 0):
            r0, r1 = float(dist[0]), float(dist[-1])
        else:
            step = float(msg.bin_distance_step)
            if not (math.isfinite(step) and step > 0):
                raise ValueError(f'bin_distance_step = {step} is not a positive distance')
            r0, r1 = _bins_geometry(n, step)
        return Ping(stamp, log_ns, self._bearing(float(msg.angle), unit, options), samples, r0, r1)

    def _echo(self, msg: Any, stamp: int, log_ns: int, unit: str, options: ImportOptions, _) -> Ping:
        data = next(getattr(msg, f) for f in ('intensities', 'profile_data', 'data') if hasattr(msg, f))
        samples = np.frombuffer(bytes(np.asarray(data, dtype=np.uint8)), dtype=np.uint8).copy()
        expected = int(getattr(msg, 'number_of_samples', 0) or 0)
        n = max(expected, len(samples))
        if n == 0:
            raise ValueError('ping has no samples')
        period = float(getattr(msg, 'sample_period', 0) or 0)
        if period > 0:
            c = float(getattr(msg, 'speed_of_sound', 0) or 0) or options.speed_of_sound
            step = c * period * 25e-9 / 2.0
        else:
            rng = float(getattr(msg, 'range', 0) or 0)
            if not rng > 0:
                raise ValueError('ping has neither a sample period nor a range')
            step = rng / n
        r0, r1 = _bins_geometry(n, step)
        return Ping(stamp, log_ns, self._bearing(float(msg.angle), unit, options), samples, r0, r1, expected)

    def _projected(self, msg: Any, stamp: int, log_ns: int, unit: str, options: ImportOptions,
                   last_frame: list) -> Frame:
        scan_time = (stamp - last_frame[0]) / 1e9 if 0 < last_frame[0] < stamp else 0.0
        last_frame[0] = stamp
        values, geom, negatives = projected_to_sector(msg, options, scan_time)
        if negatives:
            self.problem(options.topic or 'sonar', stamp, f'{negatives} negative intensities set to 0')
        return Frame(stamp, log_ns, values, geom)


def projected_to_sector(msg: Any, options: ProjectedOptions, scan_time: float = 0.0
                        ) -> tuple[np.ndarray, SectorGeometry, int]:
    """A ``ProjectedSonarImage`` (rclpy or rosbags) as sector values and geometry in increasing REP-103
    bearing on even bearing and range grids (see the module docstring), and the number of negative
    values set to 0. Raises ValueError for a malformed message."""
    dirs = np.array([(float(v.x), float(v.y), float(v.z)) for v in msg.beam_directions])
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    n, m = len(dirs), len(ranges)
    if n == 0 or m == 0:
        raise ValueError(f'image has {n} beams and {m} ranges')
    img = msg.image
    dtype = _IMAGE_DTYPES.get(int(img.dtype))
    if dtype is None:
        raise ValueError(f'image dtype code {int(img.dtype)} is not one of SonarImageData\'s 0..9')
    dt = np.dtype(dtype).newbyteorder('>' if img.is_bigendian else '<')
    raw = np.frombuffer(bytes(img.data), dtype=np.uint8) if not isinstance(img.data, np.ndarray) else img.data
    if raw.size != n * m * dt.itemsize:
        raise ValueError(f'image data has {raw.size} bytes, {n} beams x {m} ranges x {dt.itemsize} bytes '
                         f'= {n * m * dt.itemsize} expected')
    flat = raw.view(dt).astype(dt.newbyteorder('='))
    values = flat.reshape(m, n) if options.image_layout == 'range_major' else flat.reshape(n, m).T
    frame = options.beam_frame
    if frame == 'auto':
        frame = 'rep103' if np.all(np.abs(dirs[:, 2]) < 1e-9) else 'message'
    az = np.arctan2(dirs[:, 1], dirs[:, 0]) if frame == 'rep103' else np.arctan2(-dirs[:, 1], dirs[:, 2])
    if options.head_clockwise:
        az = -az
    if not np.all(np.isfinite(az)) or not np.all(np.isfinite(ranges)):
        raise ValueError('beam directions or ranges are not finite')
    order = np.argsort(az, kind='stable')
    az, values = az[order], values[:, order]
    if n > 1 and np.any(np.diff(az) <= 0):
        raise ValueError('two beams have the same bearing')
    rorder = np.argsort(ranges, kind='stable')
    ranges, values = ranges[rorder], values[rorder]
    values, a0, a1 = even_grid(values, az, axis=1)
    values, r0, r1 = even_grid(values, ranges, axis=0)
    if values.dtype not in (np.uint8, np.uint16):
        values = values.astype(np.float32)
    negatives = int((values < 0).sum()) if values.dtype.kind == 'f' else 0
    if negatives:
        values = np.maximum(values, 0)
    geom = SectorGeometry(angle_min=a0, angle_increment=(a1 - a0) / (n - 1) if n > 1 else math.radians(1.0),
                          n_beams=n, range_min=r0, range_max=r1, n_bins=m, ping_period=0.0, scan_time=scan_time)
    return np.ascontiguousarray(values), geom, negatives


def _stamp_ns(msg: Any, fallback: int) -> int:
    try:
        st = msg.header.stamp
        ns = int(st.sec) * 1_000_000_000 + int(getattr(st, 'nanosec', getattr(st, 'nsec', 0)))
    except AttributeError:
        return fallback
    return ns if ns > 0 else fallback


# -- Ping Viewer logs ------------------------------------------------------------------------------

class PingViewerRecording(Recording):
    """A Ping Viewer ``.bin`` log of a Ping360 (big-endian: header strings and ints, then records of
    a time-of-day string and a ping-protocol message, each an uint32 size + bytes).

    Record times are ``hh:mm:ss.zzz`` without a date: the date comes from ``date`` (``YYYY-MM-DD``),
    else from the first ``YYYYMMDD`` in the file name, else 1970-01-01 (UTC); a time that goes back
    by more than 12 h is the next day. Messages are parsed by the ``bluerobotics-ping`` library
    (``device_data`` 2300 and ``auto_device_data`` 2301); angles are gradians.
    """

    kind = 'pingviewer'
    TOPIC = 'ping360'
    _MAGIC = 'PingViewer sensor log file'

    def __init__(self, path: Path, date: str = '') -> None:
        super().__init__(path)
        self.data = path.read_bytes()
        self.header, self.pos = self._header()
        day = date or (m.group(1) if (m := re.search(r'(\d{8})', path.name)) else '19700101')
        try:
            fmt = '%Y-%m-%d' if '-' in day else '%Y%m%d'
            self.day_ns = int(datetime.strptime(day, fmt).replace(tzinfo=timezone.utc).timestamp()) * 1_000_000_000
        except ValueError as exc:
            raise RecordingError(f'date {day!r} is not YYYY-MM-DD') from exc

    def _string(self, pos: int) -> tuple[str, int]:
        (n,) = struct.unpack_from('>I', self.data, pos)
        if n == 0xFFFFFFFF:
            return '', pos + 4
        if pos + 4 + n > len(self.data):
            raise struct.error('string runs past the end of the file')
        return self.data[pos + 4:pos + 4 + n].replace(b'\x00', b'').decode('utf-8', 'replace'), pos + 4 + n

    def _header(self) -> tuple[dict, int]:
        try:
            magic, pos = self._string(0)
            if magic != self._MAGIC:
                raise RecordingError(f'{self.path} is not a Ping Viewer log (it starts with {magic[:40]!r})')
            (version,) = struct.unpack_from('>i', self.data, pos)
            pos += 4
            info = []
            for _ in range(5):
                s, pos = self._string(pos)
                info.append(s)
            family, sensor = struct.unpack_from('>ii', self.data, pos)
            pos += 8
        except struct.error as exc:
            raise RecordingError(f'{self.path}: the Ping Viewer header is cut off ({exc})') from exc
        return {'version': version, 'build': info, 'family': family, 'type': sensor}, pos

    def _records(self) -> Iterator[tuple[int, str, bytes]]:
        pos, last = self.pos, ''
        while pos < len(self.data):
            start = pos
            try:
                stamp, pos = self._string(pos)
                (n,) = struct.unpack_from('>I', self.data, pos)
                if pos + 4 + n > len(self.data):
                    raise struct.error('message runs past the end of the file')
                body = self.data[pos + 4:pos + 4 + n]
                pos += 4 + n
            except struct.error:
                self.problem(self.TOPIC, 0, f'the file is cut off: the record at byte {start} of {len(self.data)} '
                                            f'is incomplete; the records up to {last or "the header"} were imported')
                return
            last = stamp
            yield start, stamp, body

    def _messages(self) -> Iterator[tuple[int, str, Any]]:
        from brping import PingParser
        parser = PingParser()
        for start, stamp, body in self._records():
            msg = None
            for byte in body:
                if parser.parse_byte(byte) == parser.NEW_MESSAGE:
                    msg = parser.rx_msg
                    break
            if msg is None:
                self.problem(self.TOPIC, 0, f'record at byte {start} ({stamp}) holds no complete ping message')
                continue
            yield start, stamp, msg

    def topics(self) -> list[TopicInfo]:
        counts: dict[int, int] = {}
        for _, _, msg in self._messages():
            counts[msg.message_id] = counts.get(msg.message_id, 0) + 1
        self.problems.clear()
        return [TopicInfo(self.TOPIC, f'ping-protocol id {mid}', c, 'echo' if mid in (2300, 2301) else '')
                for mid, c in sorted(counts.items())]

    def items(self, options: ImportOptions) -> Iterator[Item]:
        unit = 'grad' if options.angle_unit == 'auto' else options.angle_unit
        day, last = self.day_ns, -1
        for start, text, msg in self._messages():
            if msg.message_id not in (2300, 2301):
                continue
            try:
                h, mnt, s = text.strip().split(':')
                tod = int(round((int(h) * 3600 + int(mnt) * 60 + float(s)) * 1e9))
            except ValueError:
                self.problem(self.TOPIC, 0, f'record at byte {start}: time {text!r} is not hh:mm:ss.zzz; skipped')
                continue
            if last >= 0 and tod < last - 12 * 3600 * 10**9:
                day += 86400 * 10**9
            last = tod
            stamp = day + tod
            samples = np.frombuffer(bytes(msg.data), dtype=np.uint8).copy()
            n = max(int(msg.number_of_samples), len(samples))
            if n == 0 or msg.sample_period <= 0:
                self.problem(self.TOPIC, stamp, 'ping without samples or sample period; skipped')
                continue
            r0, r1 = _bins_geometry(n, options.speed_of_sound * msg.sample_period * 25e-9 / 2.0)
            bearing = BagRecording._bearing(float(msg.angle), unit, options)
            yield Item('ping', self.TOPIC, stamp,
                       Ping(stamp, stamp, bearing, samples, r0, r1, int(msg.number_of_samples)))


# -- folders of polar frames -----------------------------------------------------------------------

class FolderRecording(Recording):
    """A folder of polar frames (``*.png`` 8/16-bit grey, or ``*.npy`` 2-D) in name order, plus
    ``sonar.yaml``: ``angle_min_deg``, ``angle_max_deg`` (bearing of the first and last column,
    REP-103 unless ``head_clockwise``), ``range_min``, ``range_max`` (first and last row centre),
    ``frame_period`` [s] and ``start_time`` [s since the epoch] or ``stamps`` (one per frame),
    optional ``rows: near_first | far_first`` (default near_first), ``ping_period`` [s] (0 = all
    beams at once, the default) and ``frame_id``."""

    kind = 'folder'
    TOPIC = 'frames'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        import yaml
        meta = path / 'sonar.yaml'
        if not meta.exists():
            raise RecordingError(f'{path} has no sonar.yaml describing the frames\' geometry')
        try:
            self.meta = yaml.safe_load(meta.read_text()) or {}
        except yaml.YAMLError as exc:
            raise RecordingError(f'{meta}: {exc}') from exc
        self.files = sorted(p for p in path.iterdir() if p.suffix.lower() in ('.png', '.npy'))
        missing = [k for k in ('angle_min_deg', 'angle_max_deg', 'range_min', 'range_max') if k not in self.meta]
        if missing:
            raise RecordingError(f'{meta} lacks {missing}')
        stamps = self.meta.get('stamps')
        if stamps is not None and len(stamps) != len(self.files):
            raise RecordingError(f'{meta} has {len(stamps)} stamps for {len(self.files)} frames')

    def topics(self) -> list[TopicInfo]:
        return [TopicInfo(self.TOPIC, 'polar frames', len(self.files), 'projected')]

    def _load(self, f: Path) -> np.ndarray:
        if f.suffix.lower() == '.npy':
            return np.load(f, allow_pickle=False)
        import cv2
        img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError('not a readable PNG')
        return img

    def items(self, options: ImportOptions) -> Iterator[Item]:
        m = self.meta
        period = float(m.get('frame_period', 0.1))
        t0 = int(round(float(m.get('start_time', 0.0)) * 1e9))
        a0, a1 = math.radians(float(m['angle_min_deg'])), math.radians(float(m['angle_max_deg']))
        clockwise = bool(m.get('head_clockwise', options.head_clockwise))
        for i, f in enumerate(self.files):
            stamp = int(round(float(m['stamps'][i]) * 1e9)) if m.get('stamps') else t0 + int(round(i * period * 1e9))
            try:
                v = self._load(f)
                if v.ndim != 2 or v.size == 0:
                    raise ValueError(f'frame has shape {v.shape}; expected 2-D (range bins x beams)')
                if str(m.get('rows', 'near_first')) == 'far_first':
                    v = v[::-1]
                b0, b1 = (-a0, -a1) if clockwise else (a0, a1)
                if b1 < b0:
                    v, b0, b1 = v[:, ::-1], b1, b0
                n_beams, n_bins = v.shape[1], v.shape[0]
                geom = SectorGeometry(angle_min=b0, angle_increment=(b1 - b0) / (n_beams - 1) if n_beams > 1 else 1e-3,
                                      n_beams=n_beams, range_min=float(m['range_min']),
                                      range_max=float(m['range_max']), n_bins=n_bins,
                                      ping_period=float(m.get('ping_period', 0.0)), scan_time=period)
            except (ValueError, GeometryError, OSError) as exc:
                self.problem(f.name, stamp, f'{exc}; frame skipped')
                continue
            if v.dtype.kind not in 'uf' or v.dtype.itemsize > (2 if v.dtype.kind == 'u' else 4):
                v = v.astype(np.float32)
            yield Item('frame', self.TOPIC, stamp, Frame(stamp, stamp, np.ascontiguousarray(v), geom),
                       str(m.get('frame_id', '')))


def open_recording(path: str | Path, date: str = '') -> Recording:
    """The reader for ``path`` by its form: ``.bag`` (ROS 1), ``.bin`` (Ping Viewer), a folder with
    ``sonar.yaml`` (polar frames), else a ROS 2 bag (directory, ``.mcap``, ``.db3``)."""
    path = Path(path)
    if not path.exists():
        raise RecordingError(f'{path} does not exist')
    if path.is_file() and path.suffix == '.bag':
        return BagRecording(path, ros1=True)
    if path.is_file() and path.suffix == '.bin':
        return PingViewerRecording(path, date)
    if path.is_dir() and (path / 'sonar.yaml').exists():
        return FolderRecording(path)
    if path.is_dir() and not (path / 'metadata.yaml').exists():
        # A recorder that was killed writes no metadata: read its MCAP file directly.
        files = sorted(path.glob('*.mcap'))
        if len(files) == 1:
            path = files[0]
        elif files:
            raise RecordingError(f'{path} has no metadata.yaml and {len(files)} MCAP files; import them one by one')
    return BagRecording(path, ros1=False)

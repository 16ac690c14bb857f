"""ROS 1 and ROS 2 bags of sonar drivers, read with ``rosbags``.

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
import struct
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.core.sector import GeometryError, SectorGeometry
from sonar_tracking.io.importers.conventions import TRITECH, Sensor, sensor_named_by
from sonar_tracking.io.importers.msgdefs import BUILTIN_DEFINITIONS, register_definitions
from sonar_tracking.io.importers.options import ImportOptions, ProjectedOptions
from sonar_tracking.io.importers.recording import (
    Frame,
    Item,
    Recording,
    RecordingError,
    TopicInfo,
    bins_geometry,
    even_grid,
    head_bearing,
)
from sonar_tracking.io.importers.sweeps import Ping
from sonar_tracking.msgs.projected import IMAGE_DTYPES

__all__ = ['BagRecording', 'classify', 'projected_to_sector', 'ROLES']

ROLES = ('scanline', 'echo', 'projected', 'odometry')


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

        from sonar_tracking.io.importers.ros1_salvage import Salvage, scan
        try:
            with Reader(self.path) as reader:
                for c in reader.connections:
                    defs[c.msgtype] = c.msgdef.data
                    name, count = self._topics.get(c.topic, (c.msgtype, 0))
                    self._topics[c.topic] = (name, count + c.msgcount)
            return
        except ReaderError as exc:
            reason = str(exc)
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for bytes that are not a bag
            reason = f'{type(exc).__name__}: {exc}'
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

        from sonar_tracking.io.bags import TruncatedBagWarning, bag_state, bag_topics
        try:
            with Reader(self.path) as reader:
                for c in reader.connections:
                    if c.msgdef.data:
                        defs[c.msgtype] = c.msgdef.data
                    self._topics[c.topic] = (c.msgtype, c.msgcount)
            return
        except ReaderError as exc:
            reason = str(exc)   # a cut-off MCAP file: topics from its channels, definitions built in
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for bytes that are not a bag
            reason = f'{type(exc).__name__}: {exc}'
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore', TruncatedBagWarning)  # items() reports the cut
                for t in bag_topics(self.path):
                    self._topics[t.name] = (t.msgtype, -1)
                    if t.msgdef:
                        defs[t.msgtype] = t.msgdef
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for a bad file
            raise RecordingError(f'{self.path} is not a readable ROS 2 bag ({reason}; {exc})') from exc
        if not self._topics:
            if self.path.is_dir() and not any(f.exists() for f in bag_state(self.path).files):
                raise RecordingError(f'{self.path} is not a ROS 2 bag: it holds no MCAP or sqlite3 file')
            raise RecordingError(f'{self.path} holds no topic: it is empty (its recorder ended before the first '
                                 f'message) or not a ROS 2 bag (rosbags: {reason})')

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
            from sonar_tracking.io.importers.ros1_salvage import Salvage, scan
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
        from sonar_tracking.io.bags import TruncatedBagWarning, read_bag
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

    def sensor(self, options: ImportOptions) -> tuple[Sensor | None, str]:
        """The sensor the sonar topic's message type names; a scan line (``angle``, ``bins[]``) is a
        Tritech's whatever its package is called (no other scanning sonar's driver sends bins)."""
        try:
            topic = self.sonar_topic(options)
        except RecordingError:
            return None, ''
        if topic.role == 'projected':
            return None, ''
        found = sensor_named_by(topic.msgtype)
        if found is None and topic.role == 'scanline':
            return TRITECH, f'message type {topic.msgtype} (the fields of a Tritech scan line)'
        return found, f'message type {topic.msgtype}'

    def angle_unit_used(self, options: ImportOptions) -> str:
        try:
            topic = self.sonar_topic(options)
        except RecordingError:
            return ''
        return '' if topic.role == 'projected' else self.angle_unit(topic, options)

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
            r0, r1 = bins_geometry(n, step)
        return Ping(stamp, log_ns, head_bearing(float(msg.angle), unit, options), samples, r0, r1)

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
        r0, r1 = bins_geometry(n, step)
        return Ping(stamp, log_ns, head_bearing(float(msg.angle), unit, options), samples, r0, r1, expected,
                    settings=(period, expected))

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
    dtype = IMAGE_DTYPES.get(int(img.dtype))
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

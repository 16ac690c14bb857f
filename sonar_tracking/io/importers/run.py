"""The import itself: recording items in, sectors (and odometry) out into a rosbag2 file.

Sectors are written on ``/sonar/sector`` (``sensor_msgs/Image``) and ``/sonar/sector_info``
(``sensor_msgs/LaserScan``, :func:`sonar_tracking.msgs.geometry_to_scan`) with the same header, odometry
on ``/platform/odometry``. Header stamps are the recording's; the bag time of a sector is the bag
time of its last ping (when it was complete), of odometry its own.

Intensities are either kept as recorded (``uint8`` -> ``mono8``, ``uint16`` -> ``mono16``, other
types -> ``32FC1``) with only the near-range blanking and the range cut of
:func:`sonar_tracking.core.intensity.gate_ranges` applied, or, with ``decode``, turned into linear
amplitude by :func:`sonar_tracking.core.intensity.condition` (``32FC1``).
"""
from __future__ import annotations

import dataclasses
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import sonar_tracking.msgs as ma
from sonar_tracking.core.intensity import condition, gate_ranges
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.io.importers.options import ImportOptions, ProjectedOptions
from sonar_tracking.io.importers.recording import Frame, Item, Recording
from sonar_tracking.io.importers.sweeps import SweepAssembler

__all__ = ['ImportStats', 'SectorBagWriter', 'run_import', 'condition_sector', 'SECTOR_TOPIC', 'INFO_TOPIC',
           'ODOMETRY_TOPIC']

SECTOR_TOPIC, INFO_TOPIC, ODOMETRY_TOPIC = '/sonar/sector', '/sonar/sector_info', '/platform/odometry'


@dataclass
class ImportStats:
    """What an import did: counts and problems ``(topic, stamp_ns, text)``."""

    pings_in: int = 0
    pings_out: int = 0
    frames_in: int = 0
    sectors: int = 0
    odometry: int = 0
    geometries: dict = field(default_factory=dict)   # (n_bins, n_beams, step) -> count
    problems: list = field(default_factory=list)


class SectorBagWriter:
    """Writes sectors and odometry into a new rosbag2 (MCAP or sqlite3) with the package's crash-safe
    writer (:class:`~sonar_tracking.io.bags.writer.BagWriter`: metadata version 9, as Jazzy writes).

    The bag is built in a hidden folder beside ``out`` (``.NAME.importing-PID``) and appears under
    ``out`` only in :meth:`commit`, by one rename: a failed or interrupted import leaves no bag at
    ``out`` (so a rerun is not refused). :meth:`discard` removes the hidden folder.
    """

    def __init__(self, out: Path, storage: str = 'mcap') -> None:
        from rosbags.typesys import Stores, get_typestore

        from sonar_tracking.io.bags import BagWriter
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.types = ma.RosbagsTypes(self.typestore)
        self.out = Path(out)
        self.staging = self.out.parent / f'.{self.out.name}.importing-{os.getpid()}'
        self.staging.mkdir(parents=True)
        self.writer = BagWriter(self.staging / self.out.name, storage)
        self.conns: dict[str, Any] = {}
        self.closed = False
        try:
            self.writer.open()
        except BaseException:
            self.discard()
            raise

    def _write(self, topic: str, msgtype: str, msg: Any, log_ns: int) -> None:
        conn = self.conns.get(topic)
        if conn is None:
            conn = self.conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.typestore)
        self.writer.write(conn, int(log_ns), self.typestore.serialize_cdr(msg, msgtype))

    def sector(self, stamp_ns: int, log_ns: int, values: np.ndarray, geometry: SectorGeometry, frame_id: str) -> None:
        """One sector: its Image and LaserScan with the same header."""
        image = ma.array_to_image(values, stamp_ns=stamp_ns, frame_id=frame_id, types=self.types)
        scan = ma.geometry_to_scan(geometry, amplitudes=values, stamp_ns=stamp_ns, frame_id=frame_id, types=self.types)
        self._write(SECTOR_TOPIC, 'sensor_msgs/msg/Image', image, log_ns)
        self._write(INFO_TOPIC, 'sensor_msgs/msg/LaserScan', scan, log_ns)

    def odometry(self, msg: Any, log_ns: int) -> None:
        """An Odometry of the recording (ROS 1 or ROS 2), copied field by field into the ROS 2 type; a
        PoseStamped or PoseWithCovarianceStamped becomes an Odometry with that pose and no twist."""
        if hasattr(msg, 'twist'):
            odo = self._copy(msg, 'nav_msgs/msg/Odometry')
        else:
            pose = getattr(msg.pose, 'pose', msg.pose)
            cov = np.asarray(getattr(msg.pose, 'covariance', np.zeros(36)), dtype=np.float64)
            odo = self.types.new('nav_msgs/msg/Odometry', header=self._copy(msg.header, 'std_msgs/msg/Header'),
                                 pose=self.types.new('geometry_msgs/msg/PoseWithCovariance',
                                                     pose=self._copy(pose, 'geometry_msgs/msg/Pose'), covariance=cov))
        self._write(ODOMETRY_TOPIC, 'nav_msgs/msg/Odometry', odo, log_ns)

    def _copy(self, src: Any, msgtype: str) -> Any:
        _, defs = self.typestore.fielddefs[msgtype]
        values = {}
        for name, (kind, spec) in defs:
            v = getattr(src, name)
            if int(kind) == 2:
                values[name] = self._copy(v, spec)
            elif int(kind) == 1:
                values[name] = v
            elif int(spec[0][0]) == 1:
                values[name] = np.asarray(v, dtype=np.asarray(v).dtype)
            else:
                values[name] = [self._copy(x, spec[0][1]) for x in v]
        if msgtype == 'builtin_interfaces/msg/Time' and not hasattr(src, 'nanosec'):
            values['nanosec'] = int(src.nsec)
        return self.types.new(msgtype, **values)

    def close(self) -> None:
        """End the bag (summary and metadata) in its hidden folder."""
        if not self.closed:
            self.closed = True
            self.writer.close()

    def commit(self) -> None:
        """Close the bag and move it to ``out``; FileExistsError if something appeared there meanwhile."""
        self.close()
        if self.out.exists() or self.out.is_symlink():
            raise FileExistsError(f'{self.out} appeared while importing; the import is not written')
        os.rename(self.staging / self.out.name, self.out)
        self.staging.rmdir()

    def discard(self) -> None:
        """Remove the bag being built (nothing is left at ``out``)."""
        if not self.closed:
            self.closed = True
            self.writer.abort()
        shutil.rmtree(self.staging, ignore_errors=True)


def condition_sector(values: np.ndarray, geometry: SectorGeometry,
                     options: ProjectedOptions) -> tuple[np.ndarray, SectorGeometry]:
    """The sector as written: decoded with core.intensity, or kept with only its range gating."""
    cfg = options.intensity
    if options.decode:
        amps, geom = condition(values, geometry, cfg)
        return amps.astype(np.float32), geom
    first, stop = gate_ranges(geometry, cfg.blank_range, cfg.max_range)
    if first == 0 and stop >= geometry.n_bins:
        return values, geometry
    out = np.array(values[:stop])
    out[:first] = 0
    if stop < geometry.n_bins:
        geometry = dataclasses.replace(geometry, n_bins=stop, range_max=float(geometry.ranges()[stop - 1]))
    return out, geometry


def _finite(values: np.ndarray, problem) -> np.ndarray | None:
    """``values`` with NaN and infinite cells set to 0 (no echo), each such sector reported through
    ``problem``; None (reported) when no cell is finite: nothing was measured, the sector is skipped."""
    if values.dtype.kind != 'f':
        return values
    bad = ~np.isfinite(values)
    n = int(bad.sum())
    if not n:
        return values
    if n == values.size:
        problem(f'every one of its {n} values is NaN or infinite; sector skipped')
        return None
    problem(f'{n} of its {values.size} values are NaN or infinite; set to 0 (no echo)')
    return np.where(bad, values.dtype.type(0), values)


def run_import(recording: Recording, options: ImportOptions, writer: SectorBagWriter | None) -> ImportStats:
    """Convert every item of ``recording``; ``writer=None`` only counts (``--inspect``)."""
    stats = ImportStats()
    assembler = SweepAssembler(options.pings, options.max_gap)
    frame_ids: dict[int, str] = {}

    def emit(topic: str, stamp_ns: int, log_ns: int, values: np.ndarray, geometry: SectorGeometry,
             frame_id: str) -> None:
        values = _finite(values, lambda text: recording.problem(topic, stamp_ns, text))
        if values is None:
            return
        values, geometry = condition_sector(values, geometry, options)
        key = (geometry.n_bins, geometry.n_beams, round(float(np.degrees(geometry.angle_increment)), 4))
        stats.geometries[key] = stats.geometries.get(key, 0) + 1
        stats.sectors += 1
        if writer is not None:
            writer.sector(stamp_ns, log_ns, values, geometry, options.frame_id or frame_id)

    def sectors(done) -> None:
        for s in done:
            emit(topic, s.stamp_ns, s.log_ns, s.values, s.geometry, frame_ids.get(s.stamp_ns, ''))

    item: Item
    topic = options.topic or 'sonar'
    for item in recording.items(options):
        if item.kind == 'ping':
            topic = item.topic
            frame_ids[item.payload.stamp_ns] = item.frame_id
            sectors(assembler.add(item.payload))
            if len(frame_ids) > 100000:  # keep the stamp -> frame_id map bounded
                frame_ids = {k: v for k, v in frame_ids.items() if k >= item.payload.stamp_ns - int(60e9)}
        elif item.kind == 'frame':
            f: Frame = item.payload
            stats.frames_in += 1
            emit(item.topic, f.stamp_ns, f.log_ns, f.values, f.geometry, item.frame_id)
        elif item.kind == 'odometry':
            stats.odometry += 1
            if writer is not None:
                try:
                    writer.odometry(item.payload, item.log_ns)
                except (AttributeError, TypeError, ValueError) as exc:
                    recording.problem(item.topic, item.log_ns, f'odometry cannot be converted ({exc}); skipped')
    sectors(assembler.finish())
    stats.pings_in, stats.pings_out = assembler.pings_in, assembler.pings_out
    stats.problems = list(recording.problems) + [(topic, p.stamp_ns, p.message) for p in assembler.problems]
    return stats

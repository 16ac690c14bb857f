"""What every recording reader gives: :class:`Item`s in recording order, and the helpers they share.

Every reader (:mod:`.ros_bag`, :mod:`.ping_viewer`, :mod:`.frame_folder`) yields :class:`Item`s in
recording order: a ``ping`` (scanning sonars, a :class:`~.sweeps.Ping`), a ``frame`` (imaging
sonars and folders: values bins x beams with their geometry) or an ``odometry`` (a ROS 2
``nav_msgs/Odometry`` as a rosbags message). Problems that do not stop the import (a message that
cannot be decoded, a cut-off file) go to ``problems`` as ``(topic, stamp_ns, text)``.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.io.importers.conventions import Sensor
from sonar_tracking.io.importers.options import ImportOptions, angle_to_rad

__all__ = ['Item', 'Frame', 'Recording', 'RecordingError', 'TopicInfo', 'even_grid', 'bins_geometry', 'head_bearing']


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


def bins_geometry(n: int, step: float) -> tuple[float, float]:
    """Centres of the first and last of ``n`` samples ``step`` apart, sample i covering [i, i+1) steps."""
    return 0.5 * step, (n - 0.5) * step


def head_bearing(head: float, unit: str, options: ImportOptions) -> float:
    """REP-103 bearing [rad] of a scanning head's angle ``head`` in ``unit``: s * (head - head_zero),
    s = -1 for a clockwise head, wrapped to (-pi, pi]."""
    rad = angle_to_rad(head, unit) - math.radians(options.head_zero_deg)
    return math.remainder(-rad if options.head_clockwise else rad, 2 * math.pi)


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

    def sensor(self, options: ImportOptions) -> tuple[Sensor | None, str]:
        """The sensor the recording names and how it names it (``message type X``), or ``(None, '')``."""
        return None, ''

    def angle_unit_used(self, options: ImportOptions) -> str:
        """The unit its head angles are read in (``options.angle_unit`` with ``auto`` decided), or ''
        when it has no head angles (imaging sonars and frames give bearings)."""
        return ''

    def describe(self) -> list[str]:
        """Lines ``--inspect`` adds about the recording (geometry, stamps, what was skipped)."""
        return []

    def own_conventions(self) -> dict[str, tuple[Any, str]]:
        """Conventions the recording states itself (they beat options): ``{setting: (value, source)}``."""
        return {}

    def items(self, options: ImportOptions) -> Iterator[Item]:
        raise NotImplementedError

    def problem(self, topic: str, stamp_ns: int, text: str) -> None:
        self.problems.append((topic, int(stamp_ns), text))

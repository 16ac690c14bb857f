"""Folders of polar frames (PNG or ``.npy``) with a ``sonar.yaml`` of their geometry."""
from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from sonar_tracking.core.sector import GeometryError, SectorGeometry
from sonar_tracking.io.importers.options import ImportOptions
from sonar_tracking.io.importers.recording import Frame, Item, Recording, RecordingError, TopicInfo

__all__ = ['FolderRecording']


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
            text = meta.read_bytes().decode('utf-8')
        except OSError as exc:
            raise RecordingError(f'{meta} cannot be read ({exc.strerror or exc})') from exc
        except UnicodeDecodeError as exc:
            raise RecordingError(f'{meta} is not UTF-8 text ({exc.reason} at byte {exc.start})') from exc
        try:
            data = yaml.safe_load(text) or {}
        except yaml.YAMLError as exc:
            raise RecordingError(f'{meta}: {exc}') from exc
        if not isinstance(data, dict):
            raise RecordingError(f'{meta} must be a mapping of settings, got {type(data).__name__}')
        self.files = sorted(p for p in path.iterdir() if p.suffix.lower() in ('.png', '.npy'))
        self.meta = _checked(data, meta, len(self.files))

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
        period = m['frame_period']
        t0 = int(round(m['start_time'] * 1e9))
        a0, a1 = math.radians(m['angle_min_deg']), math.radians(m['angle_max_deg'])
        clockwise = options.head_clockwise if m['head_clockwise'] is None else m['head_clockwise']
        for i, f in enumerate(self.files):
            stamp = int(round(m['stamps'][i] * 1e9)) if m['stamps'] is not None else t0 + int(round(i * period * 1e9))
            try:
                v = self._load(f)
                if v.ndim != 2 or v.size == 0:
                    raise ValueError(f'frame has shape {v.shape}; expected 2-D (range bins x beams)')
                if m['rows'] == 'far_first':
                    v = v[::-1]
                b0, b1 = (-a0, -a1) if clockwise else (a0, a1)
                if b1 < b0:
                    v, b0, b1 = v[:, ::-1], b1, b0
                n_beams, n_bins = v.shape[1], v.shape[0]
                geom = SectorGeometry(angle_min=b0, angle_increment=(b1 - b0) / (n_beams - 1) if n_beams > 1 else 1e-3,
                                      n_beams=n_beams, range_min=m['range_min'],
                                      range_max=m['range_max'], n_bins=n_bins,
                                      ping_period=m['ping_period'], scan_time=period)
                if v.dtype.kind not in 'uf' or v.dtype.itemsize > (2 if v.dtype.kind == 'u' else 4):
                    if v.dtype.kind not in 'uifb':
                        raise ValueError(f'frame values of type {v.dtype} are not numbers')
                    v = v.astype(np.float32)
            except (ValueError, GeometryError, OSError, EOFError) as exc:
                self.problem(f.name, stamp, f'{exc}; frame skipped')
                continue
            yield Item('frame', self.TOPIC, stamp, Frame(stamp, stamp, np.ascontiguousarray(v), geom), m['frame_id'])


#: Latest time a stamp may give [s since the epoch]: the seconds of a ROS ``builtin_interfaces/Time`` are int32.
_LAST_TIME = float(2**31 - 1)


def _float(value) -> float | None:
    """A YAML number, or a string that reads as one (YAML 1.1 takes ``1e300`` for text); None otherwise."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return None
    return None


def _checked(data: dict, meta: Path, n_files: int) -> dict:
    """The settings of ``sonar.yaml`` with their types and ranges checked; RecordingError naming the first
    bad one (a bad value would otherwise fail the import half-way or write nonsense stamps)."""
    missing = [k for k in ('angle_min_deg', 'angle_max_deg', 'range_min', 'range_max') if k not in data]
    if missing:
        raise RecordingError(f'{meta} lacks {missing}')

    def number(key: str, default: float | None, low: float, high: float) -> float:
        value = _float(data.get(key, default))
        if value is None:
            raise RecordingError(f'{meta}: {key} = {data.get(key)!r} is not a number')
        if not low <= float(value) <= high:
            raise RecordingError(f'{meta}: {key} = {value!r} is outside [{low:g}, {high:g}]')
        return float(value)
    out: dict = {k: number(k, None, -360.0, 360.0) for k in ('angle_min_deg', 'angle_max_deg')}
    out['range_min'] = number('range_min', None, 0.0, 1e6)
    out['range_max'] = number('range_max', None, 0.0, 1e6)
    if out['range_max'] < out['range_min']:
        raise RecordingError(f'{meta}: range_max = {out["range_max"]:g} is less than range_min = {out["range_min"]:g}')
    out['frame_period'] = number('frame_period', 0.1, 1e-6, 1e6)
    out['ping_period'] = number('ping_period', 0.0, 0.0, 1e3)
    out['start_time'] = number('start_time', 0.0, 0.0, _LAST_TIME - out['frame_period'] * max(n_files, 1))
    stamps = data.get('stamps')
    if stamps is not None:
        if not isinstance(stamps, list) or len(stamps) != n_files:
            what = f'{len(stamps)} stamps' if isinstance(stamps, list) else f'stamps = {stamps!r}'
            raise RecordingError(f'{meta} has {what} for {n_files} frames')
        out['stamps'] = []
        for i, value in enumerate(stamps):
            t = _float(value)
            if t is None or not 0.0 <= t <= _LAST_TIME:
                raise RecordingError(f'{meta}: stamps[{i}] = {value!r} is not a time in [0, {_LAST_TIME:.6g}] s')
            out['stamps'].append(t)
    else:
        out['stamps'] = None
    out['rows'] = data.get('rows', 'near_first')
    if out['rows'] not in ('near_first', 'far_first'):
        raise RecordingError(f'{meta}: rows = {out["rows"]!r} must be near_first or far_first')
    out['head_clockwise'] = data.get('head_clockwise')
    if out['head_clockwise'] is not None and not isinstance(out['head_clockwise'], bool):
        raise RecordingError(f'{meta}: head_clockwise = {out["head_clockwise"]!r} must be true or false')
    frame_id = data.get('frame_id', '')
    if not isinstance(frame_id, (str, int)) or isinstance(frame_id, bool):
        raise RecordingError(f'{meta}: frame_id = {frame_id!r} must be a name')
    out['frame_id'] = str(frame_id)
    return out

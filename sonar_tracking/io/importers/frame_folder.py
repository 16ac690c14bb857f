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

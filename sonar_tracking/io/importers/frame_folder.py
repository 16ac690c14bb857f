"""Folders of sonar frames with a ``sonar.yaml`` of their geometry and timing.

Two kinds of frame (``image:``), each a PNG/TIFF/BMP/JPEG (8- or 16-bit grey; colour only when its
channels are equal) or a 2-D ``.npy``, taken in name order (``files:`` a glob to choose them):

* ``polar`` (default): rows are range bins (``range_min``..``range_max``, first and last row centre;
  ``rows: far_first`` for images drawn with far range at the top), columns are beams at
  ``angle_min_deg``..``angle_max_deg`` evenly, or at the bearings of an angle table
  (``beam_angles_deg``: a list, or a text/CSV file of the folder, one angle per line). Unevenly
  spaced beams (a DIDSON's 0.23-0.37 deg) are resampled onto the even grid from the first to the
  last bearing with the same number of beams, by linear interpolation in angle (the rule of
  ProjectedSonarImage, :func:`~.recording.even_grid`): a point target stays within one beam of its
  bearing, where spreading the first and last angle evenly would misplace it by up to 1.4 deg.
* ``fan``: a Cartesian picture of the fan, as ARIS and DIDSON software exports it: the sonar at
  pixel ``apex_px`` ``[column, row]`` (pixel centres at whole numbers; it may lie outside the
  picture), ``metres_per_pixel``, the fan's edges ``angle_min_deg``/``angle_max_deg`` or
  ``fov_deg`` (symmetric), ``range_min``/``range_max`` its near and far radius, ``forward`` the
  picture direction of the sonar's x axis (``up``, the default, puts port on the left). It is
  resampled to polar cells filling the fan (centres half a cell inside its edges): range bins one
  pixel deep (or ``fan_bins``), beams as wide as the angle one pixel subtends at ``range_max`` (or
  ``fan_beams``), each cell the picture interpolated bilinearly at its centre from the pixels
  inside the fan only (annotations and background outside it never leak in); a cell with no such
  pixel (beyond the picture's edge) is 0, no data.

Stamps: ``start_time`` + ``frame_period`` (default), ``stamps:`` a list (one per frame in name
order), ``stamps: names`` (a date-time ``YYYYMMDD_HHMMSS[.fff]`` / ``YYYY-MM-DDTHH:MM:SS[.fff]`` or
seconds since the epoch, 9-10 digits with a fraction, or 13/16/19 digits of ms/us/ns, in each file
name) or ``stamps: FILE.csv`` (rows ``name,time`` or one ``time`` per frame in name order; a time is
seconds since the epoch or an ISO 8601 date-time; a header row is allowed). Date-times without a
zone are UTC plus ``utc_offset_hours``. Frames stamped from names or a CSV file are taken in time
order. Every setting is checked before anything is written (RecordingError naming it).
"""
from __future__ import annotations

import csv
import math
import re
from collections.abc import Iterator
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.core.sector import GeometryError, SectorGeometry
from sonar_tracking.io.importers.options import ImportOptions
from sonar_tracking.io.importers.recording import Frame, Item, Recording, RecordingError, TopicInfo, even_grid

__all__ = ['FolderRecording', 'FRAME_SUFFIXES', 'stamp_from_name', 'MAX_CELLS']

FRAME_SUFFIXES = ('.png', '.npy', '.tif', '.tiff', '.bmp', '.jpg', '.jpeg', '.pgm')
#: Most cells of a fan image's polar grid (bounded work and memory per frame).
MAX_CELLS = 16_000_000
FORWARD = {'up': (0.0, -1.0), 'down': (0.0, 1.0), 'left': (-1.0, 0.0), 'right': (1.0, 0.0)}
KEYS = {'image', 'files', 'angle_min_deg', 'angle_max_deg', 'beam_angles_deg', 'range_min', 'range_max', 'rows',
        'start_time', 'frame_period', 'stamps', 'utc_offset_hours', 'ping_period', 'head_clockwise', 'frame_id',
        'apex_px', 'metres_per_pixel', 'fov_deg', 'forward', 'fan_beams', 'fan_bins'}
#: Latest time a stamp may give [s since the epoch]: the seconds of a ROS ``builtin_interfaces/Time`` are int32.
_LAST_TIME = float(2**31 - 1)
_DATETIME = re.compile(r'(?<!\d)(\d{4})-?(\d{2})-?(\d{2})[T_ -]?(\d{2})[-:_.]?(\d{2})[-:_.]?(\d{2})'
                       r'(?:[.,_](\d{1,9}))?(?!\d)')
_EPOCH = re.compile(r'(?<!\d)(\d{9,10}(?:\.\d{1,9})?|\d{13}|\d{16}|\d{19})(?![\d])')


class FolderRecording(Recording):
    """A folder of polar frames or Cartesian fan images plus ``sonar.yaml`` (see the module docstring)."""

    kind = 'folder'
    TOPIC = 'frames'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        import yaml
        meta = path / 'sonar.yaml'
        if not meta.exists():
            raise RecordingError(missing_yaml_text(path))
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
        pattern = data.get('files', '*')
        if not isinstance(pattern, str) or not pattern:
            raise RecordingError(f'{meta}: files = {pattern!r} must be a glob such as "*.png"')
        try:
            files = sorted(p for p in path.glob(pattern) if p.is_file() and p.suffix.lower() in FRAME_SUFFIXES)
        except (ValueError, NotImplementedError) as exc:
            raise RecordingError(f'{meta}: files = {pattern!r} is not a glob of the folder ({exc})') from exc
        self.meta = _checked(data, meta, files)
        self.files = self.meta['files']
        self._maps: dict[tuple[int, ...], tuple[np.ndarray, ...]] = {}

    def topics(self) -> list[TopicInfo]:
        return [TopicInfo(self.TOPIC, f'{self.meta["image"]} frames', len(self.files), 'projected')]

    def describe(self) -> list[str]:
        m = self.meta
        if m['image'] == 'fan':
            n_bins, n_beams = self._fan_grid()
            what = (f'Cartesian fan images, apex at pixel ({m["apex_px"][0]:g}, {m["apex_px"][1]:g}), '
                    f'{m["metres_per_pixel"]:g} m per pixel, forward {m["forward"]}: resampled to {n_bins} range bins '
                    f'x {n_beams} beams over {m["angle_min_deg"]:g}..{m["angle_max_deg"]:g} deg, '
                    f'{m["range_min"]:g}..{m["range_max"]:g} m')
        elif m['beam_angles'] is not None:
            a = m['beam_angles']
            steps = np.abs(np.diff(a))
            what = (f'polar frames with an angle table of {len(a)} beams over {min(a[0], a[-1]):g}..'
                    f'{max(a[0], a[-1]):g} deg, spacing {steps.min():.3g}..{steps.max():.3g} deg'
                    + (': resampled onto an even grid of the same count' if steps.max() - steps.min() >
                       0.01 * steps.mean() else ''))
        else:
            what = f'polar frames over {m["angle_min_deg"]:g}..{m["angle_max_deg"]:g} deg'
        return [what, f'stamps from {m["stamps_from"]}']

    def own_conventions(self) -> dict[str, tuple[Any, str]]:
        if self.meta['head_clockwise'] is None:
            return {}
        return {'head_clockwise': (self.meta['head_clockwise'], f'{self.path.name}/sonar.yaml')}

    def check(self, options: ImportOptions) -> None:
        """There must be frames, and the first must fit the angle table (before an output exists)."""
        m = self.meta
        if not self.files:
            raise RecordingError(f'{self.path} has a sonar.yaml but no frame files ({", ".join(FRAME_SUFFIXES)}'
                                 f'{"" if m["files_glob"] == "*" else ", matching " + m["files_glob"]})')
        table = m['beam_angles']
        if m['image'] == 'polar' and table is not None:
            try:
                width = self._load(self.files[0]).shape[1]
            except (ValueError, OSError, EOFError):
                return                 # an unreadable frame is reported and skipped by items()
            if width != len(table):
                raise RecordingError(f'{self.path / "sonar.yaml"}: beam_angles_deg has {len(table)} angles but '
                                     f'{self.files[0].name} has {width} columns (beams)')

    def _load(self, f: Path) -> np.ndarray:
        if f.suffix.lower() == '.npy':
            v = np.load(f, allow_pickle=False)
        else:
            import cv2
            v = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
            if v is None:
                raise ValueError(f'not a readable {f.suffix[1:].upper()} image')
            if v.ndim == 3:
                grey = v[:, :, :3] if v.shape[2] >= 3 else v[:, :, :1]
                if not np.all(grey == grey[:, :, :1]):
                    raise ValueError('a colour image (its channels differ): export grey-scale frames, a colour map '
                                     'cannot be turned back into echo strength')
                v = grey[:, :, 0]
        if v.ndim != 2 or v.size == 0:
            raise ValueError(f'frame has shape {v.shape}; expected 2-D')
        if v.dtype.kind not in 'uf' or v.dtype.itemsize > (2 if v.dtype.kind == 'u' else 4):
            if v.dtype.kind not in 'uifb':
                raise ValueError(f'frame values of type {v.dtype} are not numbers')
            v = v.astype(np.float32)
        return v

    def items(self, options: ImportOptions) -> Iterator[Item]:
        m = self.meta
        clockwise = options.head_clockwise if m['head_clockwise'] is None else m['head_clockwise']
        previous = None
        for f, stamp_s in zip(self.files, m['stamps']):
            stamp = int(round(stamp_s * 1e9))
            scan_time = (stamp - previous) / 1e9 if previous is not None and stamp > previous else m['frame_period']
            previous = stamp
            try:
                v = self._load(f)
                if m['image'] == 'fan':
                    v, geom = self._fan_to_polar(v, clockwise, scan_time)
                else:
                    v, geom = self._polar(v, clockwise, scan_time)
            except (ValueError, GeometryError, OSError, EOFError) as exc:
                self.problem(f.name, stamp, f'{exc}; frame skipped')
                continue
            yield Item('frame', self.TOPIC, stamp, Frame(stamp, stamp, np.ascontiguousarray(v), geom), m['frame_id'])

    def _polar(self, v: np.ndarray, clockwise: bool, scan_time: float) -> tuple[np.ndarray, SectorGeometry]:
        m = self.meta
        if m['rows'] == 'far_first':
            v = v[::-1]
        n_bins, n_beams = v.shape
        table = m['beam_angles']
        if table is not None:
            if n_beams != len(table):
                raise ValueError(f'frame has {n_beams} columns, the angle table {len(table)} angles')
            bearings = np.radians(table) * (-1.0 if clockwise else 1.0)
            if bearings[-1] < bearings[0]:
                v, bearings = v[:, ::-1], bearings[::-1]
            v, b0, b1 = even_grid(v, bearings, axis=1)
        else:
            a0, a1 = math.radians(m['angle_min_deg']), math.radians(m['angle_max_deg'])
            b0, b1 = (-a0, -a1) if clockwise else (a0, a1)
            if b1 < b0:
                v, b0, b1 = v[:, ::-1], b1, b0
        geom = SectorGeometry(angle_min=b0, angle_increment=(b1 - b0) / (n_beams - 1) if n_beams > 1 else 1e-3,
                              n_beams=n_beams, range_min=m['range_min'], range_max=m['range_max'], n_bins=n_bins,
                              ping_period=m['ping_period'], scan_time=scan_time)
        return v, geom

    def _fan_grid(self) -> tuple[int, int]:
        """Range bins and beams of a fan image's polar grid."""
        return self.meta['fan_grid']

    def _fan_to_polar(self, img: np.ndarray, clockwise: bool, scan_time: float
                      ) -> tuple[np.ndarray, SectorGeometry]:
        import cv2
        m = self.meta
        n_bins, n_beams = self._fan_grid()
        maps = self._maps.get(img.shape)
        if maps is None:
            if len(self._maps) > 8:    # frames of many sizes: keep the cache bounded
                self._maps.clear()
            maps = self._maps[img.shape] = self._fan_maps(img.shape, n_bins, n_beams, clockwise)
        u, v, inside, weight = maps
        # Only pixels inside the fan count: a cell at the fan's edge is the mean of its neighbours
        # inside it, and a cell with none (beyond the picture) is 0, no data.
        total = cv2.remap(img.astype(np.float32) * inside, u, v, interpolation=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        polar = np.where(weight > 0, total / np.where(weight > 0, weight, 1.0), 0.0)
        if img.dtype.kind == 'u':
            polar = np.clip(np.rint(polar), 0, np.iinfo(img.dtype).max).astype(img.dtype)
        else:
            polar = polar.astype(np.float32)
        r, b = _fan_cells(m, n_bins, n_beams)
        geom = SectorGeometry(angle_min=float(b[0]), angle_increment=float(b[1] - b[0]), n_beams=n_beams,
                              range_min=float(r[0]), range_max=float(r[-1]), n_bins=n_bins,
                              ping_period=m['ping_period'], scan_time=scan_time)
        return polar, geom

    def _fan_maps(self, shape: tuple[int, ...], n_bins: int, n_beams: int, clockwise: bool
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Picture coordinates (column, row) of every polar cell centre as cv2.remap takes them, the
        picture's pixels inside the fan (1) or not (0), and each cell's interpolation weight on them."""
        import cv2
        m = self.meta
        fu, fv = FORWARD[m['forward']]
        pu, pv = fv, -fu                   # port: forward turned a quarter counter-clockwise, seen from above
        if clockwise:                      # a picture drawn mirrored (port on the right of forward up)
            pu, pv = -pu, -pv
        s = m['metres_per_pixel']
        u0, v0 = m['apex_px']
        r, b = _fan_cells(m, n_bins, n_beams)
        x, y = r[:, None] * np.cos(b[None, :]) / s, r[:, None] * np.sin(b[None, :]) / s
        u = (u0 + x * fu + y * pu).astype(np.float32)
        v = (v0 + x * fv + y * pv).astype(np.float32)
        rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
        du, dv = cols - u0, rows - v0
        px, py = (du * fu + dv * fv) * s, (du * pu + dv * pv) * s
        pr, pb = np.hypot(px, py), np.degrees(np.arctan2(py, px))
        eps = 1e-9
        inside = ((pr >= m['range_min'] - eps) & (pr <= m['range_max'] + eps) & (pb >= m['angle_min_deg'] - eps)
                  & (pb <= m['angle_max_deg'] + eps)).astype(np.float32)
        weight = cv2.remap(inside, u, v, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                           borderValue=0)
        return u, v, inside, weight


def _fan_cells(m: dict, n_bins: int, n_beams: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres of a fan's polar cells: ranges [m] and bearings [rad], each half a cell inside the
    fan's edges (``range_min``..``range_max``, ``angle_min_deg``..``angle_max_deg``), so every cell
    lies in the fan."""
    dr = (m['range_max'] - m['range_min']) / n_bins
    db = math.radians(m['angle_max_deg'] - m['angle_min_deg']) / n_beams
    return (m['range_min'] + (np.arange(n_bins) + 0.5) * dr,
            math.radians(m['angle_min_deg']) + (np.arange(n_beams) + 0.5) * db)


def missing_yaml_text(path: Path) -> str:
    """What a folder of frames without ``sonar.yaml`` needs, as an error message."""
    n = sum(1 for p in path.iterdir() if p.suffix.lower() in FRAME_SUFFIXES)
    return (f'{path} holds {n} frame file{"" if n == 1 else "s"} but no sonar.yaml describing their geometry and '
            'timing; write one (docs/importers.md, "Folders of frames"): polar frames need angle_min_deg, '
            'angle_max_deg (or beam_angles_deg), range_min, range_max; Cartesian fan images image: fan, apex_px, '
            'metres_per_pixel, fov_deg, range_min, range_max; both start_time and frame_period, or stamps')


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


def stamp_from_name(name: str, offset_h: float = 0.0) -> float | None:
    """Seconds since the epoch written in a file name (see the module docstring), or None."""
    stem = Path(name).stem if Path(name).suffix.lower() in FRAME_SUFFIXES else name
    for m in _DATETIME.finditer(stem):
        y, mo, d, h, mi, s, frac = m.groups()
        try:
            t = datetime(int(y), int(mo), int(d), int(h), int(mi), int(s), tzinfo=timezone.utc)
        except ValueError:
            continue
        seconds = t.timestamp() - offset_h * 3600.0
        return seconds + (int(frac.ljust(9, '0')) / 1e9 if frac else 0.0)
    for m in _EPOCH.finditer(stem):
        text = m.group(1)
        if '.' in text or len(text) <= 10:
            return float(text)
        return int(text) / {13: 1e3, 16: 1e6, 19: 1e9}[len(text)]
    return None


def _time_value(text: str, offset_h: float) -> float | None:
    """A CSV time: seconds since the epoch, or an ISO 8601 date-time (no zone: UTC + offset_h)."""
    value = _float(text.strip())
    if value is not None:
        return value if math.isfinite(value) else None
    try:
        t = datetime.fromisoformat(text.strip())
    except ValueError:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone(timedelta(hours=offset_h)))
    return t.timestamp()


def _read_table(path: Path, what: str) -> list[list[str]]:
    """Rows of a small CSV/text file (comma, semicolon, tab or space separated; ``#`` comments dropped)."""
    if not path.is_file():
        raise RecordingError(f'{what}: {path} does not exist')
    if path.stat().st_size > 50_000_000:
        raise RecordingError(f'{what}: {path} is larger than 50 MB; not a table')
    try:
        text = path.read_bytes().decode('utf-8-sig')
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f'{what}: {path} is not readable UTF-8 text ({exc})') from exc
    rows = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            delimiter = next((d for d in ',;\t' if d in line), None)
            fields = next(csv.reader([line], delimiter=delimiter)) if delimiter else line.split()
            rows.append([f.strip() for f in fields] or [''])
    return rows


def _angle_table(value, meta: Path) -> np.ndarray:
    """The ``beam_angles_deg`` of ``sonar.yaml``: a list or a file of the folder, checked."""
    if isinstance(value, str):
        rows = _read_table(meta.parent / value, f'{meta}: beam_angles_deg')
        angles: list = []
        for i, fields in enumerate(rows):
            a = _float(fields[-1])
            if a is None and i == 0 and len(rows) > 1:
                continue                       # a header row
            if a is None:
                raise RecordingError(f'{meta}: beam_angles_deg: line {i + 1} of {value} ({",".join(fields)!r}) '
                                     'does not end in an angle')
            angles.append(a)
        where = value
    elif isinstance(value, list):
        angles, where = [_float(a) for a in value], 'beam_angles_deg'
        bad = next((i for i, a in enumerate(angles) if a is None), None)
        if bad is not None:
            raise RecordingError(f'{meta}: beam_angles_deg[{bad}] = {value[bad]!r} is not a number')
    else:
        raise RecordingError(f'{meta}: beam_angles_deg = {value!r} must be a list of angles or the name of a file '
                             'of the folder holding them')
    table = np.array(angles, dtype=np.float64)
    return _checked_angles(table, meta, where)


def _checked_angles(a: np.ndarray, meta: Path, where: str) -> np.ndarray:
    """An angle table [deg] of at least two finite angles within +-360 deg, strictly growing or falling."""
    if len(a) < 2:
        raise RecordingError(f'{meta}: {where} holds {len(a)} angle(s); at least 2 are needed')
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > 360.0):
        raise RecordingError(f'{meta}: {where}: every angle must be a finite number within +-360 deg')
    d = np.diff(a)
    if not (np.all(d > 0) or np.all(d < 0)):
        i = int(np.argmax(d <= 0) if d[0] > 0 else np.argmax(d >= 0))
        raise RecordingError(f'{meta}: {where}: the angles must grow (or fall) from beam to beam; beam {i + 2} '
                             f'({a[i + 1]:g} deg) follows beam {i + 1} ({a[i]:g} deg), counting from 1')
    return a


def _stamps(spec, meta: Path, files: list[Path], offset_h: float) -> tuple[list[Path], list[float] | None, str]:
    """Frames (in time order when stamped from names or a file), their stamps [s] (None = from
    start_time and frame_period) and where the stamps come from."""
    if spec is None:
        return files, None, 'start_time + frame_period'
    if isinstance(spec, list):
        if len(spec) != len(files):
            raise RecordingError(f'{meta} has {len(spec)} stamps for {len(files)} frames')
        out = []
        for i, value in enumerate(spec):
            t = _float(value)
            if t is None or not 0.0 <= t <= _LAST_TIME:
                raise RecordingError(f'{meta}: stamps[{i}] = {value!r} is not a time in [0, {_LAST_TIME:.6g}] s')
            out.append(t)
        return files, out, 'the stamps list of sonar.yaml'
    if spec == 'names':
        out = []
        for f in files:
            t = stamp_from_name(f.name, offset_h)
            if t is None:
                raise RecordingError(f'{meta}: stamps: names, but {f.name} holds no date-time (YYYYMMDD_HHMMSS[.fff]) '
                                     'and no seconds since the epoch')
            out.append(t)
        where = 'the file names'
    elif isinstance(spec, str):
        rows = _read_table(meta.parent / spec, f'{meta}: stamps')
        by_name: dict[str, float] = {}
        in_order: list[float] = []
        for i, fields in enumerate(rows):
            t = _time_value(fields[-1], offset_h)
            if t is None and i == 0:
                continue                       # a header row
            if t is None:
                raise RecordingError(f'{meta}: stamps: line {i + 1} of {spec} ({",".join(fields)!r}) does not end '
                                     'in a time (seconds since the epoch or an ISO 8601 date-time)')
            if len(fields) > 1:
                by_name[fields[0]] = t
            else:
                in_order.append(t)
        if by_name:
            out = []
            for f in files:
                t = by_name.get(f.name, by_name.get(f.stem))
                if t is None:
                    raise RecordingError(f'{meta}: stamps: {spec} has no row for {f.name}')
                out.append(t)
        elif len(in_order) != len(files):
            raise RecordingError(f'{meta}: stamps: {spec} has {len(in_order)} times for {len(files)} frames')
        else:
            out = in_order
        where = spec
    else:
        raise RecordingError(f'{meta}: stamps = {spec!r} must be a list of times, "names" or a CSV file of the folder')
    for f, t in zip(files, out):
        if not 0.0 <= t <= _LAST_TIME:
            raise RecordingError(f'{meta}: the stamp of {f.name} ({t!r} s) is not a time in [0, {_LAST_TIME:.6g}] s')
    order = sorted(range(len(files)), key=lambda i: (out[i], files[i].name))
    return [files[i] for i in order], [out[i] for i in order], where


def _checked(data: dict, meta: Path, files: list[Path]) -> dict:
    """The settings of ``sonar.yaml`` with their types and ranges checked; RecordingError naming the first
    bad one (a bad value would otherwise fail the import half-way or write nonsense stamps)."""
    unknown = sorted(set(map(str, data)) - KEYS)
    if unknown:
        raise RecordingError(f'{meta}: unknown setting(s) {unknown}; the settings are {sorted(KEYS)}')
    image = data.get('image', 'polar')
    if image not in ('polar', 'fan'):
        raise RecordingError(f'{meta}: image = {image!r} must be polar (rows = ranges, columns = beams) or fan '
                             '(a Cartesian picture of the fan)')
    out: dict = {'image': image, 'files_glob': data.get('files', '*')}

    def number(key: str, default: float | None, low: float, high: float) -> float:
        value = _float(data.get(key, default))
        if value is None:
            raise RecordingError(f'{meta}: {key} = {data.get(key)!r} is not a number')
        if not low <= float(value) <= high:
            raise RecordingError(f'{meta}: {key} = {value!r} is outside [{low:g}, {high:g}]')
        return float(value)

    needed = ['range_min', 'range_max']
    if image == 'fan':
        needed += ['apex_px', 'metres_per_pixel']
        if 'fov_deg' not in data:
            needed += ['angle_min_deg', 'angle_max_deg']
    elif 'beam_angles_deg' not in data:
        needed += ['angle_min_deg', 'angle_max_deg']
    missing = [k for k in needed if k not in data]
    if missing:
        raise RecordingError(f'{meta} lacks {missing}')
    if 'beam_angles_deg' in data and ('angle_min_deg' in data or 'angle_max_deg' in data or image == 'fan'):
        raise RecordingError(f'{meta}: beam_angles_deg is for polar frames, instead of angle_min_deg and '
                             'angle_max_deg; give one or the other')
    if 'fov_deg' in data:
        if 'angle_min_deg' in data or 'angle_max_deg' in data:
            raise RecordingError(f'{meta}: give fov_deg or angle_min_deg and angle_max_deg, not both')
        fov = number('fov_deg', None, 0.0, 360.0)
        if fov <= 0:
            raise RecordingError(f'{meta}: fov_deg = {fov:g} must be more than 0')
        out['angle_min_deg'], out['angle_max_deg'] = -fov / 2.0, fov / 2.0
    elif 'angle_min_deg' in data:
        out.update({k: number(k, None, -360.0, 360.0) for k in ('angle_min_deg', 'angle_max_deg')})
    out['beam_angles'] = _angle_table(data['beam_angles_deg'], meta) if 'beam_angles_deg' in data else None
    out['range_min'] = number('range_min', None, 0.0, 1e6)
    out['range_max'] = number('range_max', None, 0.0, 1e6)
    if out['range_max'] < out['range_min']:
        raise RecordingError(f'{meta}: range_max = {out["range_max"]:g} is less than range_min = {out["range_min"]:g}')
    out['frame_period'] = number('frame_period', 0.1, 1e-6, 1e6)
    out['ping_period'] = number('ping_period', 0.0, 0.0, 1e3)
    offset_h = number('utc_offset_hours', 0.0, -14.0, 14.0)
    out['start_time'] = number('start_time', 0.0, 0.0, _LAST_TIME - out['frame_period'] * max(len(files), 1))
    out['files'], stamps, out['stamps_from'] = _stamps(data.get('stamps'), meta, files, offset_h)
    if stamps is None:
        stamps = [out['start_time'] + i * out['frame_period'] for i in range(len(files))]
    out['stamps'] = stamps
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
    if image == 'fan':
        _check_fan(data, meta, out, number)
    return out


def _check_fan(data: dict, meta: Path, out: dict, number) -> None:
    """The fan settings of ``sonar.yaml`` into ``out``, checked."""
    apex = data['apex_px']
    pair = [_float(v) for v in apex] if isinstance(apex, list) and len(apex) == 2 else []
    coords = [v for v in pair if v is not None and math.isfinite(v) and abs(v) <= 1e6]
    if len(coords) != 2:
        raise RecordingError(f'{meta}: apex_px = {apex!r} must be [column, row] of the pixel at the sonar')
    out['apex_px'] = (coords[0], coords[1])
    out['metres_per_pixel'] = number('metres_per_pixel', None, 0.0, 1e3)
    if out['metres_per_pixel'] <= 0:
        raise RecordingError(f'{meta}: metres_per_pixel = {out["metres_per_pixel"]:g} must be more than 0')
    out['forward'] = data.get('forward', 'up')
    if out['forward'] not in FORWARD:
        raise RecordingError(f'{meta}: forward = {out["forward"]!r} must be one of {sorted(FORWARD)} (the picture '
                             'direction of the sonar\'s x axis)')
    if out['angle_max_deg'] <= out['angle_min_deg']:
        raise RecordingError(f'{meta}: the fan\'s angle_max_deg = {out["angle_max_deg"]:g} must be more than '
                             f'angle_min_deg = {out["angle_min_deg"]:g} (port is positive)')
    if out['range_max'] <= out['range_min']:
        raise RecordingError(f'{meta}: the fan\'s range_max must be more than its range_min')
    for key in ('fan_beams', 'fan_bins'):
        value = data.get(key, 0)
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 100_000 or value == 1:
            raise RecordingError(f'{meta}: {key} = {value!r} must be a whole number of at least 2 (0 = from the '
                                 'picture\'s scale)')
        out[key] = value
    span = math.radians(out['angle_max_deg'] - out['angle_min_deg'])
    n_bins = out['fan_bins'] or max(2, int(round((out['range_max'] - out['range_min']) / out['metres_per_pixel'])))
    n_beams = out['fan_beams'] or max(2, int(math.ceil(span * out['range_max'] / out['metres_per_pixel'])))
    out['fan_grid'] = (n_bins, n_beams)
    if n_bins * n_beams > MAX_CELLS:
        raise RecordingError(f'{meta}: the fan resamples to {n_bins} range bins x {n_beams} beams, more than '
                             f'{MAX_CELLS} cells; give fan_bins and fan_beams, or a coarser metres_per_pixel')

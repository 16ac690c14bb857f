"""``sonar_eval track``: run the IMM-IPDA tracker on recorded detections in a CSV file.

Input (``--input``), comma-separated with a header row:

* required columns ``scan, t, x, y``: scan number, scan time [s], world position [m];
* optional ``r_xx, r_xy, r_yy`` (measurement covariance [m^2]) and ``clutter_density`` [1/m^2].
  Without them (or where a cell is empty) the tracker uses ``detection.sigma`` and
  ``clutter.density``. Other columns are ignored.

Rows are grouped by ``scan`` (in order of first appearance); every row of a scan must carry the
scan's time. A row whose ``x`` and ``y`` are both empty marks a scan without detections.
Bad rows (unparsable numbers, a time that differs from its scan's, NaN, a covariance that is not
positive definite, a clutter density that is not positive) are reported on stderr with their
line number and skipped; the rest is processed. The first :data:`MAX_REPORTS` bad rows (and as
many notes about scans) are printed one by one, the others are counted and summarised by reason
at the end. A scan whose time is not after the previous scan's is dropped (same time) or restarts
the tracker (earlier), as in the node.

Refused with exit code 2 (the message says why): a header that names a used column twice, no
header within the first :data:`MAX_HEADER_LINES` lines or a header line longer than
:data:`MAX_LINE` bytes (``/dev/zero``, a binary file), a line running over :data:`MAX_RUN` bytes
without a line end. Memory and work per line are bounded; input that goes on for ever with
proper lines (a pipe) is processed as a stream.

Output (``--output``, ``-`` for stdout): ``scan, t, track_id, x, y, vx, vy, existence, confirmed,
mode_cv, mode_ccw, mode_cw``, one row per track per scan (``--confirmed-only``: confirmed tracks).

``--params FILE.yaml``: tracker settings, as a ROS parameter file (the ``imm_ipda_tracker``
section of e.g. ``config/imm_ipda.yaml``; node-only settings such as ``world_frame`` are accepted
and ignored) or as a plain mapping of setting names to values.
"""
from __future__ import annotations

import argparse
import collections
import csv
import math
import re
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, TextIO

import numpy as np

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.timeline import TimeWentBack
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig, TrackingError
from sonar_tracking.core.tracking.measurements import check_measurements

__all__ = ['add_arguments', 'main_args', 'load_params', 'read_detections', 'run', 'DetectionReader', 'Scan',
           'OUTPUT_COLUMNS', 'MAX_LINE']

REQUIRED = ('scan', 't', 'x', 'y')
OPTIONAL = ('r_xx', 'r_xy', 'r_yy', 'clutter_density')
OUTPUT_COLUMNS = ('scan', 't', 'track_id', 'x', 'y', 'vx', 'vy', 'existence', 'confirmed', 'mode_cv', 'mode_ccw',
                  'mode_cw')
NODE_NAME = 'imm_ipda_tracker'


class InputError(ValueError):
    """The input cannot be used at all (file, header or parameters); the message says why."""


@dataclass
class Scan:
    """The usable rows of one scan: the file line of each, positions, covariances and clutter
    densities (defaults filled in where the file gave none)."""

    number: int
    t: float
    lines: list[int] = field(default_factory=list)
    z: list[np.ndarray] = field(default_factory=list)
    R: list[np.ndarray] = field(default_factory=list)
    rho: list[float] = field(default_factory=list)
    last_line: int = 0


def load_params(path: Path) -> TrackerConfig:
    """Tracker settings from a YAML file (ROS parameter file or plain mapping); InputError if unusable."""
    from sonar_tracking.io import param_files
    try:
        data = param_files.load(path)
    except param_files.ParamFileError as exc:
        raise InputError(str(exc)) from None
    patterns = [pattern for pattern, _ in param_files.sections(data)]
    if patterns:
        flat = param_files.parameters_for(data, NODE_NAME)
        if flat is None:
            raise InputError(f'{path}: no section applies to {NODE_NAME} among {patterns}')
    else:
        flat = param_files.flatten(data)
    known = {s.name for s in TrackerConfig.settings()}
    node_only = _node_only_settings()
    unknown = sorted(set(flat) - known - node_only)
    if unknown:
        raise InputError(f'{path}: unknown parameter(s) {unknown}; known: {sorted(known)}')
    try:
        return TrackerConfig.from_flat({k: (tuple(v) if isinstance(v, list) else v)
                                        for k, v in flat.items() if k in known})
    except ConfigError as exc:
        raise InputError(f'{path}: {exc}') from None


def _node_only_settings() -> set[str]:
    """Settings the node adds to the tracker's (read from the node's config without starting ROS)."""
    try:
        from sonar_tracking.nodes.imm_ipda_tracker import TrackerNodeConfig
    except ImportError:       # no rclpy: fall back to the names the node is known to add
        return {'world_frame', 'publish_tentative', 'markers_tentative', 'marker_scale'}
    return {s.name for s in TrackerNodeConfig.settings()} - {s.name for s in TrackerConfig.settings()}


#: Longest input line read; a longer one is a bad row (memory stays bounded).
MAX_LINE = 1 << 20
#: Longest line skipped as a bad row; a longer one ends the input (no line end in sight: not a text CSV).
MAX_RUN = 16 << 20
#: Lines read looking for the header (blank ones before it are skipped).
MAX_HEADER_LINES = 1000
#: Bad rows, and notes about scans, printed one by one; the others are counted and summarised.
MAX_REPORTS = 20
#: Rows parsed before their measurements are checked together (one vectorised check per block).
BLOCK = 4096
_BOMS = {b'\xff\xfe': 'UTF-16', b'\xfe\xff': 'UTF-16', b'\xff\xfe\x00\x00': 'UTF-32'}


class _Lines:
    """Text lines of a byte stream: UTF-8 (a BOM is dropped), a line that is not UTF-8 read as Latin-1
    with one warning, CR-only line ends (old Mac spreadsheets) understood, lines longer than
    :data:`MAX_LINE` reported and replaced by an empty line (so line numbers stay right)."""

    def __init__(self, raw: BinaryIO, report) -> None:
        self.raw, self.report = raw, report
        self.latin1 = 0
        self.header_read = False         # set by the reader once it has its header

    def __iter__(self) -> Iterator[str]:
        block = self.raw.read(64 << 10)
        for bom, name in sorted(_BOMS.items(), key=lambda kv: -len(kv[0])):
            if block.startswith(bom):
                raise InputError(f'the file is {name}; save it as CSV (UTF-8)')
        if block.startswith(b'\xef\xbb\xbf'):
            block = block[3:]
        cr_only = b'\r' in block and b'\n' not in block
        number, pending, skipping, skipped = 0, b'', False, 0
        while block:
            if cr_only:
                block = block.replace(b'\r', b'\n')
            parts = (pending + block).split(b'\n')
            pending = parts.pop()
            for part in parts:
                number += 1
                if skipping or len(part) > MAX_LINE:     # (the end of) a line too long
                    if not self.header_read:
                        raise InputError(f'line {number}, where the header belongs, is longer than {MAX_LINE} '
                                         f'bytes: not a CSV file')
                    skipping = False
                    self.report(number, f'the line is longer than {MAX_LINE} bytes')
                    yield '\n'
                else:
                    yield self._decode(part, number) + '\n'
            if len(pending) > MAX_LINE:
                if not self.header_read:
                    raise InputError(f'line {number + 1}, where the header belongs, is longer than {MAX_LINE} bytes: '
                                     f'not a CSV file')
                if not skipping:
                    skipped = 0
                skipped += len(pending)
                pending, skipping = b'', True
                if skipped > MAX_RUN:
                    raise InputError(f'line {number + 1} runs over {MAX_RUN} bytes without a line end: the rest of '
                                     f'the input is not a text CSV')
            block = self.raw.read(1 << 20)
        if skipping:
            self.report(number + 1, f'the line is longer than {MAX_LINE} bytes')
        elif pending:
            yield self._decode(pending, number + 1)

    def _decode(self, data: bytes, number: int) -> str:
        try:
            return data.decode('utf-8')
        except UnicodeDecodeError as exc:
            if not self.latin1:
                print(f'warning: line {number} is not UTF-8 ({exc.reason} at byte {exc.start}); it and any '
                      f'further such line are read as Latin-1', file=self.report.errors)
            self.latin1 += 1
            return data.decode('latin-1')


class _Reports:
    """Bad-row reports, printed in line order one block at a time: the first ``limit`` one by one, the
    others counted by reason for :meth:`summary`. Also the notes about scans (:meth:`note`), likewise."""

    def __init__(self, errors: TextIO, limit: int = MAX_REPORTS) -> None:
        self.errors, self.pending, self.count = errors, [], 0
        self.limit = limit
        self.shown = {'row': 0, 'note': 0}
        self.hidden: dict[str, collections.Counter] = {'row': collections.Counter(), 'note': collections.Counter()}

    def __call__(self, line: int, reason: str) -> None:
        self.pending.append((line, reason))
        self.count += 1

    def flush(self) -> None:
        for line, reason in sorted(self.pending):
            self._show('row', f'line {line}: {reason}; row skipped', reason)
        self.pending = []

    def note(self, text: str) -> None:
        """A message about a scan (printed like a bad row: the first ``limit``, then counted)."""
        self._show('note', text, text)

    def _show(self, what: str, text: str, reason: str) -> None:
        if self.shown[what] < self.limit:
            self.shown[what] += 1
            print(text, file=self.errors)
            return
        hidden = self.hidden[what]
        kind = _KIND.sub('#', reason)
        hidden[kind if kind in hidden or len(hidden) < 50 else 'other reasons'] += 1

    def summary(self) -> None:
        """The reports not printed, by reason (numbers and quoted values shown as #)."""
        for what, name in (('row', 'bad rows'), ('note', 'notes about scans')):
            hidden = self.hidden[what]
            if hidden:
                reasons = '; '.join(f'{n} x {kind}' for kind, n in hidden.most_common(10))
                more = f'; {len(hidden) - 10} more reasons' if len(hidden) > 10 else ''
                print(f'... and {sum(hidden.values())} more {name} not shown (only the first {self.limit} are): '
                      f'{reasons}{more}', file=self.errors)


#: What makes two reasons differ but not their kind: quoted values and numbers.
_KIND = re.compile(r"'[^']*'|-?\b\d[\w.+-]*")


def _float(text: str, column: str, decimal_comma: bool) -> float:
    try:
        return float(text)
    except ValueError:
        if decimal_comma and ',' in text:
            try:
                return float(text.replace(',', '.'))
            except ValueError:
                pass
        raise ValueError(f'{column} = {text.strip()!r} is not a number') from None


def _scan_number(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not value.is_integer():
        raise ValueError(f'scan = {text.strip()!r} is not an integer')
    return int(value)


class DetectionReader:
    """Scans of a detections CSV, read as a stream (see the module docstring for the format).

    Rows are checked where they are read (numbers, NaN, a time that differs from its scan's; the
    measurement rule of :func:`~sonar_tracking.core.tracking.measurements.check_measurements`
    once per block of rows); a bad row is reported with its line number and skipped before it can
    start, end or time a scan. Memory holds one block of rows and one scan.
    """

    def __init__(self, raw: BinaryIO, errors: TextIO, config: TrackerConfig) -> None:
        self.report = _Reports(errors)
        self.lines_source = _Lines(raw, self.report)
        self.lines = iter(self.lines_source)
        self.reader = csv.reader(self.lines)
        self.config = config
        self._last_line = self._line_offset = 0
        self.decimal_comma = False
        header = self._header()
        self.col = {name: header.index(name) for name in REQUIRED + OPTIONAL if name in header}
        self.has = {name: name in self.col for name in OPTIONAL}
        self.has_cov = all(self.has[c] for c in ('r_xx', 'r_xy', 'r_yy'))
        if any(self.has[c] for c in ('r_xx', 'r_xy', 'r_yy')) and not self.has_cov:
            print('note: covariance needs all of r_xx, r_xy, r_yy; using detection.sigma for every row', file=errors)
        self.use_rho = self.has['clutter_density'] and config.clutter.source == 'detection'
        self.done: dict[int, int] = {}      # scan number -> line where it ended
        self.scan: Scan | None = None
        self.n_scans = self.n_detections = 0

    @property
    def bad(self) -> int:
        return self.report.count

    def _header(self) -> list[str]:
        for row in self._rows():
            if row is None:
                raise InputError(f'line {self._last_line}, where the header belongs, is not readable as CSV')
            if not any(c.strip() for c in row[1]):
                if self._last_line >= MAX_HEADER_LINES:
                    raise InputError(f'no header in the first {MAX_HEADER_LINES} lines')
                continue
            line, cells = row
            header = [h.strip().lower() for h in cells]
            for delimiter in (';', '\t'):
                if len(cells) == 1 and delimiter in cells[0]:
                    # Spreadsheets in locales with decimal commas separate by ';' (or tabs).
                    self._line_offset = self._last_line
                    self.reader = csv.reader(self.lines, delimiter=delimiter)
                    header = [h.strip().lower() for h in cells[0].split(delimiter)]
                    self.decimal_comma = True
                    break
            missing = [c for c in REQUIRED if c not in header]
            if missing:
                raise InputError(f'the header (line {line}) lacks column(s) {missing}; it has {header}')
            twice = sorted({c for c in REQUIRED + OPTIONAL if header.count(c) > 1})
            if twice:
                raise InputError(f'the header (line {line}) names column(s) {twice} more than once: which one holds '
                                 f'the values is not clear; rename or remove the others')
            self.lines_source.header_read = True
            return header
        raise InputError('the input is empty: expected a header with columns ' + ', '.join(REQUIRED))

    def _rows(self) -> Iterator[tuple[int, list[str]] | None]:
        """``(first line, cells)`` per record; None for a record csv refused (reported)."""
        while True:
            try:
                cells = next(self.reader)
            except StopIteration:
                return
            except csv.Error as exc:
                self._last_line = self._line_offset + self.reader.line_num
                self.report(self._last_line, f'unreadable CSV ({exc})')
                yield None
                continue
            first, self._last_line = self._last_line + 1, self._line_offset + self.reader.line_num
            yield first, cells

    def scans(self) -> Iterator[Scan]:
        """The scans in file order, each once its last row has been read."""
        block: list[tuple] = []
        for row in self._rows():
            if row is not None:
                parsed = self._parse(*row)
                if parsed is not None:
                    block.append(parsed)
            if len(block) >= BLOCK:
                yield from self._block(block)
                block = []
        yield from self._block(block)
        if self.scan is not None:
            yield self._finish()
        self.report.flush()

    def _parse(self, line: int, cells: list[str]) -> tuple | None:
        """``(line, scan, t, x, y, r_xx, r_xy, r_yy, rho, has_R, has_rho)`` of a row; x is None for a
        scan without detections; None (reported) for a bad row or a blank one."""
        col = self.col
        try:      # a complete row of plain numbers (the usual case); anything else goes the long way
            number, t = int(cells[col['scan']]), float(cells[col['t']])
            x, y = float(cells[col['x']]), float(cells[col['y']])
            if self.has_cov:
                rxx, rxy, ryy = float(cells[col['r_xx']]), float(cells[col['r_xy']]), float(cells[col['r_yy']])
            else:
                rxx = rxy = ryy = 0.0
            rho = float(cells[col['clutter_density']]) if self.use_rho else 0.0
            if math.isfinite(t):
                return (line, number, t, x, y, rxx, rxy, ryy, rho, self.has_cov, self.use_rho)
        except (ValueError, IndexError):
            pass
        return self._parse_cells(line, cells)

    def _parse_cells(self, line: int, cells: list[str]) -> tuple | None:
        """:meth:`_parse` for rows with empty or missing cells, decimal commas or errors (says which)."""
        col, comma = self.col, self.decimal_comma

        def cell(name: str) -> str:
            i = col.get(name)
            return cells[i] if i is not None and i < len(cells) else ''
        try:
            xs, ys = cell('x'), cell('y')
            if not (xs.strip() or ys.strip()):
                if not any(c.strip() for c in cells):
                    return None                                     # a blank line
                number, t = _scan_number(cell('scan')), _float(cell('t'), 't', comma)
                if not math.isfinite(t):
                    raise ValueError(f't = {t} is not finite')
                return (line, number, t, None, None, 0.0, 0.0, 0.0, 0.0, False, False)
            number, t = _scan_number(cell('scan')), _float(cell('t'), 't', comma)
            if not math.isfinite(t):
                raise ValueError(f't = {t} is not finite')
            x, y = _float(xs, 'x', comma), _float(ys, 'y', comma)
            rxx = rxy = ryy = 0.0
            has_R = False
            if self.has_cov:
                cov = (cell('r_xx'), cell('r_xy'), cell('r_yy'))
                given = [bool(c.strip()) for c in cov]
                if any(given) and not all(given):
                    raise ValueError('r_xx, r_xy, r_yy must be given together')
                if all(given):
                    rxx, rxy, ryy = (_float(v, c, comma) for v, c in zip(cov, ('r_xx', 'r_xy', 'r_yy')))
                    has_R = True
            rho, has_rho = 0.0, False
            if self.use_rho and cell('clutter_density').strip():
                rho, has_rho = _float(cell('clutter_density'), 'clutter_density', comma), True
        except ValueError as exc:
            self.report(line, str(exc))
            return None
        return (line, number, t, x, y, rxx, rxy, ryy, rho, has_R, has_rho)

    def _block(self, block: list[tuple]) -> Iterator[Scan]:
        """Check a block's measurements together, then group the good rows into scans."""
        det = [r for r in block if r[3] is not None]
        if det:
            cfg = self.config
            a = np.array([r[3:9] for r in det], dtype=float)                     # x y rxx rxy ryy rho
            has_R = np.array([r[9] for r in det])
            has_rho = np.array([r[10] for r in det])
            s2 = cfg.detection.sigma ** 2
            comps = np.where(has_R[:, None], a[:, 2:5], (s2, 0.0, s2))
            R = comps[:, [0, 1, 1, 2]].reshape(-1, 2, 2)
            rho = np.where(has_rho, a[:, 5], cfg.clutter.density)
            keep, rejected = check_measurements(a[:, :2], R, rho)
            bad_rows = set()
            for r in rejected:
                bad_rows.add(id(det[r.index]))
                self.report(det[r.index][0], r.reason)
            values = {id(r): (a[i, :2], R[i], rho[i]) for i, r in enumerate(det) if keep[i]}
        else:
            bad_rows, values = set(), {}
        for r in block:
            if id(r) in bad_rows:
                continue
            line, number = r[0], r[1]
            if self.scan is not None and number != self.scan.number:
                yield self._finish()
            if self.scan is None:
                if number in self.done:
                    self.report(line, f'scan {number} ended at line {self.done[number]}: the rows of a scan must '
                                      f'be consecutive (sort the file by scan)')
                    continue
                self.scan = Scan(number, r[2])
            scan = self.scan
            if r[2] != scan.t:
                self.report(line, f't = {r[2]:g} differs from the time of scan {number} ({scan.t:g})')
                continue
            scan.last_line = line
            if r[3] is not None:
                z, Ri, rhoi = values[id(r)]
                scan.lines.append(line)
                scan.z.append(z)
                scan.R.append(Ri)
                scan.rho.append(rhoi)
        self.report.flush()

    def _finish(self) -> Scan:
        scan, self.scan = self.scan, None
        self.done[scan.number] = scan.last_line
        self.n_scans += 1
        self.n_detections += len(scan.z)
        return scan


def read_detections(stream: BinaryIO, errors: TextIO, config: TrackerConfig | None = None
                    ) -> tuple[list[Scan], dict[str, bool], int]:
    """All scans of a CSV at once: ``(scans, columns present, bad rows)`` (for small files and tests;
    ``sonar_eval track`` streams with :class:`DetectionReader`)."""
    reader = DetectionReader(stream, errors, config or TrackerConfig())
    scans = list(reader.scans())
    return scans, reader.has, reader.bad


_ROW = '%d,%.10g,%d,%.10g,%.10g,%.10g,%.10g,%.10g,%d,%.10g,%.10g,%.10g\n'


def run(scans: Iterable[Scan], config: TrackerConfig, out: TextIO, errors: TextIO, confirmed_only: bool = False,
        reports: _Reports | None = None) -> tuple[int, int]:
    """Track the scans and write the output rows. Returns ``(rows written, rows rejected by the tracker)``.

    Notes about scans and rows the tracker rejects go to ``reports`` (the reader's, so they are
    bounded and summarised alike), else straight to ``errors``."""
    def note(text: str) -> None:
        if reports is None:
            print(text, file=errors)
        else:
            reports.note(text)
    tracker = ImmIpdaTracker(config)
    out.write(','.join(OUTPUT_COLUMNS) + '\n')
    written = rejected = 0
    for scan in scans:
        n = len(scan.z)
        z = np.array(scan.z, dtype=float).reshape(n, 2)
        R = np.array(scan.R, dtype=float).reshape(n, 2, 2)
        rho = np.array(scan.rho, dtype=float).reshape(n)
        try:
            try:
                tracks = tracker.step(scan.t, z, R, rho)
            except TimeWentBack as back:    # the file holds another recording from here on
                note(f'scan {scan.number}: time went backwards by {back.back:.6g} s (another recording?): '
                     'all tracks removed')
                tracker.reset()
                tracks = tracker.step(scan.t, z, R, rho)
        except TrackingError as exc:
            note(f'scan {scan.number} (t = {scan.t:g}): skipped: {exc}')
            continue
        rep = tracker.report
        if rep.duplicate_stamp:
            note(f'scan {scan.number}: t = {scan.t:g} repeats the previous scan\'s time; scan skipped')
            continue
        if rep.reset:
            note(f'scan {scan.number}: {rep.reset}')
        for r in rep.rejected:          # the reader checked the same rule: only for a changed config
            rejected += 1
            note(f'line {scan.lines[r.index]}: {r.reason}; row skipped')
        if confirmed_only:
            tracks = tracks[tracks['confirmed'] != 0]
        if len(tracks):
            cols = [tracks[c].tolist() for c in ('track_id', 'x', 'y', 'vx', 'vy', 'existence', 'confirmed',
                                                 'mode_cv', 'mode_ccw', 'mode_cw')]
            out.write(''.join(_ROW % (scan.number, scan.t, *row) for row in zip(*cols)))
            written += len(tracks)
    return written, rejected


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``sonar_eval track``."""
    parser.add_argument('--input', required=True, help='detections CSV: scan,t,x,y[,r_xx,r_xy,r_yy,clutter_density]')
    parser.add_argument('--output', required=True, help='tracks CSV to write (- for stdout)')
    parser.add_argument('--params', type=Path, default=None,
                        help='tracker parameters (YAML: ROS parameter file such as config/imm_ipda.yaml, or a mapping)')
    parser.add_argument('--confirmed-only', action='store_true', help='write confirmed tracks only')


def main_args(args: argparse.Namespace) -> int:
    """Run ``sonar_eval track`` with parsed arguments; returns the exit status (2: unusable input)."""
    errors = sys.stderr
    try:
        config = load_params(args.params) if args.params else TrackerConfig()
        try:
            source = open(args.input, 'rb')  # noqa: SIM115 - closed by the `with source` below
        except OSError as exc:
            raise InputError(f'cannot read {args.input}: {exc.strerror}') from None
        try:
            reader = DetectionReader(source, errors, config)
        except BaseException:
            source.close()
            raise
    except InputError as exc:
        print(f'error: {exc}', file=errors)
        return 2
    with source:
        if not reader.has['clutter_density'] and config.clutter.source == 'detection':
            print(f'note: no clutter_density column: using clutter.density = {config.clutter.density:g} /m^2',
                  file=errors)
        try:
            out = sys.stdout if args.output == '-' else open(args.output, 'w', newline='')  # noqa: SIM115
        except OSError as exc:
            print(f'error: cannot write {args.output}: {exc.strerror}', file=errors)
            return 2
        try:
            written, rejected = run(reader.scans(), config, out, errors, args.confirmed_only, reader.report)
        except InputError as exc:
            reader.report.flush()
            reader.report.summary()
            print(f'error: {exc}', file=errors)
            return 2
        except OSError as exc:
            print(f'error: reading {args.input} or writing {args.output} failed: {exc.strerror or exc}', file=errors)
            return 1
        finally:
            if out is not sys.stdout:
                out.close()
    reader.report.summary()
    print(f'{reader.n_scans} scans, {reader.n_detections - rejected} detections used, {reader.bad + rejected} bad '
          f'rows skipped, {written} track rows written to {args.output}', file=errors)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry (``python -m sonar_tracking.cli.track_csv``); ``sonar_eval track`` is the usual one."""
    parser = argparse.ArgumentParser(prog='sonar_eval track', description=__doc__.split('\n\n')[0])
    add_arguments(parser)
    return main_args(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())

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
line number and skipped; the rest is processed. A scan whose time is not after the previous
scan's is dropped (same time) or restarts the tracker (earlier), as in the node.

Output (``--output``, ``-`` for stdout): ``scan, t, track_id, x, y, vx, vy, existence, confirmed,
mode_cv, mode_ccw, mode_cw``, one row per track per scan (``--confirmed-only``: confirmed tracks).

``--params FILE.yaml``: tracker settings, as a ROS parameter file (the ``imm_ipda_tracker``
section of e.g. ``config/imm_ipda.yaml``; node-only settings such as ``world_frame`` are accepted
and ignored) or as a plain mapping of setting names to values.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig, TrackingError

__all__ = ['add_arguments', 'main_args', 'load_params', 'read_detections', 'Scan', 'OUTPUT_COLUMNS']

REQUIRED = ('scan', 't', 'x', 'y')
OPTIONAL = ('r_xx', 'r_xy', 'r_yy', 'clutter_density')
OUTPUT_COLUMNS = ('scan', 't', 'track_id', 'x', 'y', 'vx', 'vy', 'existence', 'confirmed', 'mode_cv', 'mode_ccw',
                  'mode_cw')
NODE_NAME = 'imm_ipda_tracker'


class InputError(ValueError):
    """The input cannot be used at all (file, header or parameters); the message says why."""


@dataclass
class Scan:
    """The usable rows of one scan: values and the file line each came from."""

    number: int
    t: float
    lines: list[int] = field(default_factory=list)
    z: list[tuple[float, float]] = field(default_factory=list)
    R: list[tuple[float, float, float] | None] = field(default_factory=list)     # None: not given
    rho: list[float | None] = field(default_factory=list)


def _flatten(mapping: dict, prefix: str = '') -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(value, name + '.'))
        else:
            out[name] = value
    return out


def load_params(path: Path) -> TrackerConfig:
    """Tracker settings from a YAML file (ROS parameter file or plain mapping); InputError if unusable."""
    import yaml
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f'cannot read parameters from {path}: {exc}') from None
    if not isinstance(data, dict):
        raise InputError(f'{path}: expected a mapping of parameters, got {type(data).__name__}')
    sections = {k: v for k, v in data.items() if isinstance(v, dict) and 'ros__parameters' in v}
    if sections:
        section = sections.get(NODE_NAME) or sections.get('/**')
        if section is None:
            raise InputError(f'{path}: no {NODE_NAME} (or /**) section among {sorted(sections)}')
        data = section['ros__parameters'] or {}
    flat = _flatten(data)
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


def _number(text: str, column: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f'{column} = {text!r} is not a number') from None


def read_detections(stream: TextIO, errors: TextIO) -> tuple[list[Scan], dict[str, bool], int]:
    """Parse the CSV into scans; report bad rows to ``errors``. Returns ``(scans, columns present, bad rows)``."""
    reader = csv.reader(stream)
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise InputError('the input is empty: expected a header with columns ' + ', '.join(REQUIRED)) from None
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(f'the header lacks column(s) {missing}; it has {header}')
    col = {name: header.index(name) for name in REQUIRED + OPTIONAL if name in header}
    has = {name: name in col for name in OPTIONAL}
    has_cov = all(has[c] for c in ('r_xx', 'r_xy', 'r_yy'))
    if any(has[c] for c in ('r_xx', 'r_xy', 'r_yy')) and not has_cov:
        print('note: covariance needs all of r_xx, r_xy, r_yy; using detection.sigma for every row', file=errors)
    scans: dict[int, Scan] = {}
    bad = 0

    def cell(row: list[str], name: str) -> str:
        i = col.get(name)
        return row[i].strip() if i is not None and i < len(row) else ''

    for row in reader:
        line = reader.line_num
        if not any(c.strip() for c in row):
            continue
        try:
            scan_text = cell(row, 'scan')
            number = int(scan_text) if scan_text.lstrip('+-').isdigit() else None
            if number is None:
                raise ValueError(f'scan = {scan_text!r} is not an integer')
            t = _number(cell(row, 't'), 't')
            if not math.isfinite(t):
                raise ValueError(f't = {t} is not finite')
            scan = scans.get(number)
            if scan is None:
                scan = scans[number] = Scan(number, t)
            elif t != scan.t:
                raise ValueError(f't = {t:g} differs from the time of scan {number} ({scan.t:g})')
            xs, ys = cell(row, 'x'), cell(row, 'y')
            if not xs and not ys:
                continue                     # a scan without detections
            z = (_number(xs, 'x'), _number(ys, 'y'))
            cov = tuple(cell(row, c) for c in ('r_xx', 'r_xy', 'r_yy')) if has_cov else ('', '', '')
            if any(cov) and not all(cov):
                raise ValueError('r_xx, r_xy, r_yy must be given together')
            R = tuple(_number(v, c) for v, c in zip(cov, ('r_xx', 'r_xy', 'r_yy'))) if all(cov) else None
            rho_text = cell(row, 'clutter_density')
            rho = _number(rho_text, 'clutter_density') if rho_text else None
        except ValueError as exc:
            bad += 1
            print(f'line {line}: {exc}; row skipped', file=errors)
            continue
        scan.lines.append(line)
        scan.z.append(z)
        scan.R.append(R)
        scan.rho.append(rho)
    return list(scans.values()), has, bad


def _fmt(v: Any) -> str:
    if isinstance(v, (float, np.floating)):
        return format(float(v), '.10g')
    return str(v)


def run(scans: list[Scan], config: TrackerConfig, out: TextIO, errors: TextIO, confirmed_only: bool = False
        ) -> tuple[int, int]:
    """Track the scans and write the output rows. Returns ``(rows written, rows rejected by the tracker)``."""
    tracker = ImmIpdaTracker(config)
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow(OUTPUT_COLUMNS)
    sigma2 = config.detection.sigma ** 2
    written = rejected = 0
    for scan in scans:
        n = len(scan.z)
        z = np.array(scan.z, dtype=float).reshape(n, 2)
        sigma_row = (sigma2, 0.0, sigma2)
        comps = np.array([r if r is not None else sigma_row for r in scan.R], dtype=float).reshape(n, 3)
        R = np.empty((n, 2, 2))
        R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = comps[:, 0], comps[:, 1], comps[:, 1], comps[:, 2]
        rho = np.array([v if v is not None else config.clutter.density for v in scan.rho], dtype=float)
        try:
            tracks = tracker.step(scan.t, z, R, rho)
        except TrackingError as exc:
            print(f'scan {scan.number} (t = {scan.t:g}): skipped: {exc}', file=errors)
            continue
        rep = tracker.report
        if rep.duplicate_stamp:
            print(f'scan {scan.number}: t = {scan.t:g} repeats the previous scan\'s time; scan skipped', file=errors)
            continue
        if rep.reset:
            print(f'scan {scan.number}: {rep.reset}', file=errors)
        for r in rep.rejected:
            rejected += 1
            print(f'line {scan.lines[r.index]}: {r.reason}; row skipped', file=errors)
        if confirmed_only:
            tracks = tracks[tracks['confirmed'] != 0]
        for rec in tracks:
            writer.writerow([scan.number, _fmt(scan.t), int(rec['track_id'])]
                            + [_fmt(rec[c]) for c in ('x', 'y', 'vx', 'vy', 'existence')]
                            + [int(rec['confirmed'])] + [_fmt(rec[c]) for c in ('mode_cv', 'mode_ccw', 'mode_cw')])
            written += 1
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
            with open(args.input, newline='') as f:
                scans, has, bad = read_detections(f, errors)
        except OSError as exc:
            raise InputError(f'cannot read {args.input}: {exc.strerror}') from None
    except InputError as exc:
        print(f'error: {exc}', file=errors)
        return 2
    if not has['clutter_density'] and config.clutter.source == 'detection':
        print(f'note: no clutter_density column: using clutter.density = {config.clutter.density:g} /m^2',
              file=errors)
    try:
        out = sys.stdout if args.output == '-' else open(args.output, 'w', newline='')
    except OSError as exc:
        print(f'error: cannot write {args.output}: {exc.strerror}', file=errors)
        return 2
    try:
        written, rejected = run(scans, config, out, errors, args.confirmed_only)
    finally:
        if out is not sys.stdout:
            out.close()
    n_det = sum(len(s.z) for s in scans)
    print(f'{len(scans)} scans, {n_det - rejected} detections used, {bad + rejected} bad rows skipped, '
          f'{written} track rows written to {args.output}', file=errors)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry (``python -m sonar_tracking.tools.track_csv``); ``sonar_eval track`` is the usual one."""
    parser = argparse.ArgumentParser(prog='sonar_eval track', description=__doc__.split('\n\n')[0])
    add_arguments(parser)
    return main_args(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())

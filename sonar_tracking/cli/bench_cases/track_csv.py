"""``sonar_eval track`` speed on a 1e6-row detections CSV (issue 21: under 15 s).

The file (written once per case, not timed) holds one constant-velocity target and uniform clutter
over 4 km x 4 km, ``N`` detections per scan, one scan every 2 s, with covariance and clutter density
columns. Each case times one whole run of ``sonar_eval track`` (read, track, write the tracks CSV)
or the reading alone, so it is run once per repeat.

* ``track_csv.read.1e6``: reading and checking the 1e6 rows into scans (no tracker).
* ``track_csv.run.1e6.dN``: the whole command, ``N`` detections per scan (1e6 / N scans).
"""
from __future__ import annotations

import atexit
import io
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from sonar_tracking.cli.bench import Case, register

ROWS = 1_000_000
LIMIT_S = 15.0


def write_detections(path: Path, rows: int, per_scan: int, seed: int = 1) -> None:
    """A detections CSV of ``rows`` rows, ``per_scan`` per scan (seeded)."""
    rng = np.random.default_rng(seed)
    with open(path, 'w') as f:
        f.write('scan,t,x,y,r_xx,r_xy,r_yy,clutter_density\n')
        for k in range(rows // per_scan):
            p = np.array([100.0, -50.0]) + np.array([2.0, 1.0]) * 2.0 * k
            pts = np.vstack([p + rng.normal(0, 3, 2), rng.uniform(-2000, 2000, (per_scan - 1, 2))])
            t = 10 + 2.0 * k
            f.write(''.join(f'{k},{t:g},{x:.3f},{y:.3f},9,1,9,2e-6\n' for x, y in pts))


def _file(per_scan: int) -> Path:
    folder = tempfile.mkdtemp(prefix='bench_track_csv_')
    atexit.register(shutil.rmtree, folder, True)
    path = Path(folder) / f'det_{per_scan}.csv'
    write_detections(path, ROWS, per_scan)
    return path


def _read():
    from sonar_tracking.cli.track_csv import DetectionReader
    from sonar_tracking.core.tracking import TrackerConfig
    path = _file(20)

    def once() -> float:
        t0 = time.perf_counter()
        with open(path, 'rb') as raw:
            n = sum(len(s.z) for s in DetectionReader(raw, io.StringIO(), TrackerConfig()).scans())
        assert n == ROWS
        return time.perf_counter() - t0
    return once


def _run(per_scan: int):
    def make():
        from sonar_tracking.cli.track_csv import main
        path = _file(per_scan)

        def once() -> float:
            t0 = time.perf_counter()
            code = main(['--input', str(path), '--output', str(path.with_suffix('.tracks.csv'))])
            assert code == 0
            return time.perf_counter() - t0
        return once
    return make


register(Case(name='track_csv.read.1e6', group='track_csv', make=_read, self_timed=True, repeats=1,
              description='sonar_eval track: read and check 1e6 CSV rows into scans (20 per scan), no tracker'))
for _n in (10, 100):
    register(Case(name=f'track_csv.run.1e6.d{_n}', group='track_csv', make=_run(_n), self_timed=True, repeats=1,
                  limit_s=LIMIT_S, description=f'sonar_eval track end to end on 1e6 rows, {_n} detections per scan '
                                               f'({ROWS // _n} scans)'))

"""Compiled kernels ready before data arrives: a short synthetic run of a component at start.

numba compiles a kernel at its first call (per argument types) and caches the machine code, so a
fresh install spends seconds in its first scans: a node fed at the sensor's rate meanwhile queues
or drops messages, and a pipeline stopped soon after (``make demo`` at ``rate:=0``) loses them.
A node therefore runs its component here once, before it subscribes, on a few seeded synthetic
scans that take every compiled path the component has (the tests check that a real run
afterwards compiles nothing new). With the cache filled this costs a fraction of a second; the
first start after an install compiles every kernel (seconds).

The synthetic data come from a fixed seed of their own; nothing here touches the caller's
generator or state.
"""
from __future__ import annotations

import time

import numpy as np

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
from sonar_tracking.core.records import DETECTION_DTYPE
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.core.tracking import TrackerConfig
from sonar_tracking.core.tracking.detections import detections_to_measurements
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker

__all__ = ['tracker', 'detector', 'gpf']

_SEED = 20261126


def tracker(config: TrackerConfig) -> float:
    """Steps a throwaway :class:`ImmIpdaTracker` of ``config`` through eight synthetic scans: a
    target confirmed in sparse clutter (the direct pair test, track management and the duplicate
    test), a scan without detections, two of 300 uniform detections (the strip search, the pair
    budget and chunks) and one from a source without covariance and clutter-density fields; and
    its initial covariance. Returns the seconds it took."""
    started = time.perf_counter()
    rng = np.random.default_rng(_SEED)
    known = TrackerConfig().flat()   # a node's config carries its ROS settings too
    flat = {k: v for k, v in config.flat().items() if k in known}
    try:   # confirm within the few scans, where the settings allow it
        settings = TrackerConfig.from_flat({**flat, 'existence.confirm': min(flat['existence.confirm'], 0.5)})
    except ConfigError:
        settings = TrackerConfig.from_flat(flat)
    trk = ImmIpdaTracker(settings)
    trk.initial_covariance()
    for k in range(8):
        target = np.array([[5.0 * k, 2.0 * k]]) + rng.normal(0.0, 1.0, (1, 2))
        n_clutter = 300 if k in (5, 6) else 4
        clutter = rng.uniform(-2000.0, 2000.0, (n_clutter, 2))
        xy = np.concatenate([target, clutter]) if k != 4 else np.zeros((0, 2))    # and a scan without any
        records = np.zeros(len(xy), DETECTION_DTYPE)
        records['x'], records['y'] = xy[:, 0], xy[:, 1]
        records['cov_xx'] = records['cov_yy'] = 4.0
        records['clutter_density'] = 1e-5
        if k == 7:   # a source without covariance or density fields
            xy_only = np.zeros(len(records), [('x', '<f8'), ('y', '<f8')])
            xy_only['x'], xy_only['y'] = records['x'], records['y']
            records = xy_only
        z, R, rho, _ = detections_to_measurements(records)
        trk.step(float(k), z, R, rho)
    return time.perf_counter() - started


def detector(config: DetectorConfig, desired_density: float) -> float:
    """Runs a throwaway :class:`ActiveDetector` of ``config`` over four synthetic sectors: three of
    Rayleigh clutter (SCMDE's neighbour search and edge correction, the ESC focus disc, CFAR's
    window sums) and one of quiet water with 15 strong cells (the joining of sparse above-threshold
    cells), the last two from a moved pose (the structure background's world map). Returns the
    seconds it took."""
    started = time.perf_counter()
    rng = np.random.default_rng(_SEED)
    det = ActiveDetector(config, desired_density)
    geometry = SectorGeometry(range_min=10.0, range_max=500.0, n_bins=100, angle_min=-0.3,
                              angle_increment=0.01, n_beams=60)
    for k in range(4):
        amplitudes = rng.rayleigh(1.0, (geometry.n_bins, geometry.n_beams))
        if k == 3:   # 15 cells 20 apart above any threshold, the rest far below
            amplitudes *= 1e-3
            amplitudes[10:100:20, 5:60:20] = 100.0
        pose = (0.0, 0.0, 0.0) if k < 2 else (5.0, 2.0, 0.05)
        det.process(amplitudes, geometry, pose, focus_xy=(250.0, 0.0), stamp=float(k))
    return time.perf_counter() - started


def gpf(make_tracker) -> float:
    """Steps a throwaway GPF frame tracker, ``make_tracker()``, through four synthetic 40 x 40
    frames with two bright regions (window features of templates, particles and estimates, with
    grey levels per pixel and per image). Returns the seconds it took."""
    from sonar_tracking.core.fls import ImageGrid
    from sonar_tracking.core.records import REGION_DTYPE
    started = time.perf_counter()
    rng = np.random.default_rng(_SEED)
    trk = make_tracker()
    grid = ImageGrid(resolution=0.1, width=40, height=40, origin_x=0.0, origin_y=-2.0)
    rows, cols = np.indices(grid.shape)
    for k in range(4):
        img = rng.gamma(16.0, 1.0 / 16.0, grid.shape)
        xy = np.array([[1.2 + 0.05 * k, -0.8], [2.8 - 0.05 * k, 0.8]])
        for x, y in xy:
            r, c = grid.point_to_pixel(x, y)
            img += 10.0 * np.exp(-0.5 * (((cols - c) / 1.5) ** 2 + ((rows - r) / 4.0) ** 2))
        regions = np.zeros(len(xy), REGION_DTYPE)
        regions['region_id'] = np.arange(1, len(xy) + 1)
        regions['x'], regions['y'] = xy[:, 0], xy[:, 1]
        trk.step(5.0 * k, img.astype(np.float32), grid, regions, (0.0, 0.0, 0.0))
    return time.perf_counter() - started


def main() -> int:
    """``python -m sonar_tracking.ros.warmup``: fill the kernel cache (default settings of each
    component), e.g. once after an install, before a demo or a test run."""
    from sonar_tracking import process
    from sonar_tracking.core.gpf import GpfTracker
    process.prepare()
    imaging = DetectorConfig.from_flat({'threshold.method': 'ca', 'cells.grouping': 'connected', 'cells.merge_bins': 3,
                                        'cells.merge_beams': 3, 'structure.enabled': True})   # CFAR, blobs, structure
    seconds = (tracker(TrackerConfig.from_flat({'imm.models': 'cv,ccw,cw'})) + detector(DetectorConfig(), 1e-5)
               + detector(imaging, 1e-5) + gpf(lambda: GpfTracker(rng=np.random.default_rng(0))))
    print(f'compiled kernels ready in {seconds:.1f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

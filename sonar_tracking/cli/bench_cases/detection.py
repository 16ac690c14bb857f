"""Detection stage speed (issue: active detector): threshold + SCMDE + ESC on one sector; an imaging
sonar's frame with the Oculus preset (issue 31)."""
from __future__ import annotations

import itertools
import math
import time

import numpy as np

from sonar_tracking.cli.bench import Case, register


def _detect_256x128():
    from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
    from sonar_tracking.sim import HarbourConfig, HarbourSonar, Scene
    from sonar_tracking.sim.motion import StaticTrajectory
    cell = 2 * math.sqrt(3) * 5.0
    cfg = HarbourConfig(range_min=1000.0, range_max=1000.0 + 256.5 * cell, bearing_min_deg=-22.2,
                        bearing_max_deg=-22.2 + 128.5 * 2 * math.sqrt(3) * 0.1)
    sonar = HarbourSonar(cfg)
    assert sonar.geometry.shape == (256, 128)
    rng = np.random.default_rng(0)
    scene = Scene([], StaticTrajectory(-2000.0, 0.0), lam=1.2)
    sectors = [sonar.next_sector(scene, rng) for _ in range(50)]
    det = ActiveDetector(DetectorConfig.from_flat({'threshold.initial': 4.5}))
    for s in sectors[:20]:  # let ESC settle near its operating point
        det.process(s.amplitudes, s.geometry, s.pose)
    cycle = itertools.cycle(sectors)

    def step():
        s = next(cycle)
        return det.process(s.amplitudes, s.geometry, s.pose)
    return step


register(Case(name='detection.sector_256x128', group='detection', make=_detect_256x128, limit_s=1e-3,
              description='threshold + converted covariances + SCMDE + ESC, 256 x 128 cells, ~250 detections'))


# -- big sectors (issue 19): bounded time and memory per scan ------------------------------------

_BIG = 2000
_STATS: dict[str, dict] = {}


def _big_sector(name: str, flat: dict, tau_for_cells: int | None = None, scans: int = 4):
    """A 2,000 x 2,000 cell sector of Rayleigh clutter (sigma 1) per scan, a few different ones in turn.

    ``tau_for_cells``: a fixed threshold giving about that many cells above it per scan
    (``P(a > tau) = exp(-tau^2 / 2)``). The peak of memory allocated during one scan (tracemalloc,
    which sees numpy's buffers) and the process's peak RSS are reported with the time.
    """
    import tracemalloc

    from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
    from sonar_tracking.core.sector import SectorGeometry

    g = SectorGeometry(angle_min=-math.pi / 4, angle_increment=(math.pi / 2) / (_BIG - 1), n_beams=_BIG,
                       range_min=10.0, range_max=10.0 + 0.05 * (_BIG - 1), n_bins=_BIG, scan_time=1.0)
    rng = np.random.default_rng(0)
    sectors = [rng.rayleigh(1.0, g.shape).astype(np.float32) for _ in range(scans)]
    if tau_for_cells is not None:
        tau = math.sqrt(-2.0 * math.log(tau_for_cells / g.n_bins / g.n_beams))
        flat = flat | {'threshold.initial': tau, 'threshold.maximum': max(30.0, tau), 'esc.enabled': False}
    det = ActiveDetector(DetectorConfig.from_flat(flat))
    cycle = itertools.cycle(sectors)
    clock = itertools.count()

    def step():
        return det.process(next(cycle), g, stamp=float(next(clock)))
    for _ in range(3):
        step()
    tracemalloc.start()
    result = step()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    _STATS[name] = {'detections': len(result.detections), 'found': result.found, 'cut': result.cut,
                    'structure': result.structure, 'peak_alloc_MB': peak / 2 ** 20,
                    'sector_MB': sectors[0].nbytes / 2 ** 20}
    return step


def _big_derived(name: str):
    def derived(r) -> dict:
        import resource
        return dict(_STATS.get(name, {}), rss_peak_MB=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    return derived


for _name, _flat, _cells, _text in (
        ('detection.sector_2000x2000', {'threshold.initial': 4.5}, None,
         'ESC on from threshold 4.5'),
        ('detection.sector_2000x2000_20k', {}, 20_000,
         '~20,000 cells above a fixed threshold, cells.max_detections 2000 keeps the strongest'),
        ('detection.sector_2000x2000_20k_connected', {'cells.grouping': 'connected'}, 20_000,
         'the same, connected grouping (8-connected groups)'),
        ('detection.sector_2000x2000_20k_structure',
         {'structure.enabled': True, 'structure.max_length': 6.0, 'structure.elongated_length': 3.0}, 20_000,
         'the same with static-structure rejection: shape gates, persistent-echo map, learning')):
    register(Case(name=_name, group='detection', make=lambda n=_name, f=_flat, c=_cells: _big_sector(n, f, c),
                  repeats=100, min_time=0.0, derived=_big_derived(_name),
                  description=f'2,000 x 2,000 cell sector per scan: {_text}; peak allocation per scan and '
                              'process peak RSS'))


# -- imaging frames (issue 31): the Oculus preset's detector within a 20 Hz frame ----------------

_FRAMES = 40          # frames rendered once (2 s of the scenario), replayed in turn with fresh stamps
_RATE_HZ = 20.0
_FRAME_TIMES: dict[str, list[float]] = {}


def imaging_detector_config():
    """The detector settings of the Oculus M750d preset (``config/sensors/oculus_m750d.yaml``,
    ``/**/active_detector``) for the simulator's frames: 8-bit log counts over 60 dB, as
    ``config/stack_imaging.yaml`` sets them."""
    from sonar_tracking.core.detection import DetectorConfig
    from sonar_tracking.io import param_files
    from sonar_tracking.resources import config_path
    preset = param_files.parameters_for(param_files.load(config_path('sensors/oculus_m750d.yaml')), 'active_detector')
    known = DetectorConfig().flat()     # the preset also holds the node's own settings (input_qos)
    flat = {k: v for k, v in (preset or {}).items() if k in known}
    return DetectorConfig.from_flat(flat | {'intensity.coding': 'db', 'intensity.db_span': 60.0})


def _imaging_frame(name: str, moving: bool):
    """``ActiveDetector.process`` on 512 x 1000 frames of ``imaging_diver`` with the Oculus preset
    (CA-CFAR, connected blobs merged over 10 x 12 cells, structure rejection, ESC every 20 frames),
    each frame timed alone. ``moving``: the pose changes every frame (0.5 m/s forward, 0.2 m/s
    sideways, 2.3 deg/s of yaw), so the structure background keeps its world map as well;
    otherwise the platform stays where the scenario starts it."""
    from sonar_tracking.core.detection import ActiveDetector
    from sonar_tracking.sim import SimConfig, Simulator
    sim = Simulator(SimConfig.for_scenario('imaging_diver', 'oculus_m750d'), np.random.default_rng(0))
    frames = [sim.next_sector() for _ in range(_FRAMES)]
    assert frames[0].geometry.shape == (1000, 512)
    det = ActiveDetector(imaging_detector_config())
    x0, y0, yaw0 = frames[0].pose
    clock = itertools.count()
    times = _FRAME_TIMES.setdefault(name, [])
    times.clear()

    def process() -> float:
        k = next(clock)
        s = frames[k % _FRAMES]
        t = k / _RATE_HZ
        pose = (x0 + 0.5 * t, y0 + 0.2 * t, yaw0 + 0.04 * t) if moving else (x0, y0, yaw0)
        started = time.perf_counter()
        det.process(s.amplitudes, s.geometry, pose, stamp=t)
        return time.perf_counter() - started
    for _ in range(_FRAMES):     # first calls: compiled kernels loaded, maps allocated, ESC under way
        process()

    def timed() -> float:
        seconds = process()
        times.append(seconds)
        return seconds
    return timed


def _frame_figures(name: str):
    def derived(r) -> dict:
        t = np.asarray(_FRAME_TIMES.get(name, [np.nan]))
        return {'p99_ms': 1e3 * float(np.percentile(t, 99)), 'frames': len(t),
                'x_real_time_20Hz': (1.0 / _RATE_HZ) / r.median_s}
    return derived


for _name, _moving, _limit, _text in (
        ('detection.imaging_frame', False, 0.020, 'static platform'),
        ('detection.imaging_frame_moving', True, 0.025, 'pose changing every frame (world map as well)')):
    register(Case(name=_name, group='detection', make=lambda n=_name, m=_moving: _imaging_frame(n, m),
                  self_timed=True, repeats=200, limit_s=_limit, derived=_frame_figures(_name),
                  description=f'Oculus M750d preset (CA-CFAR, connected blobs, structure, ESC), 512 x 1000 frames of '
                              f'imaging_diver pre-rendered, one ActiveDetector.process per frame: {_text}; p99 '
                              'beside the median'))

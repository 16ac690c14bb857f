"""Detection stage speed (issue: active detector): threshold + SCMDE + ESC on one sector."""
from __future__ import annotations

import itertools
import math

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

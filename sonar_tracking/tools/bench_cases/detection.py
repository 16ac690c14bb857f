"""Detection stage speed (issue: active detector): threshold + SCMDE + ESC on one sector."""
from __future__ import annotations

import itertools
import math

import numpy as np

from ..bench import Case, register


def _detect_256x128():
    from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
    from sonar_tracking.core.sim import HarbourConfig, HarbourSonar, Scene
    from sonar_tracking.core.sim.motion import StaticTrajectory
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

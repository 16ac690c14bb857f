"""FLS front end (issue 8): one 400 x 400 frame through the modified median filter, region growing
and all 30 features of 20 regions.

The frame is a SeaKing 675 kHz full turn (400 beams of 0.9 deg, 400 range bins of 5 cm to 20 m)
with 20 targets, painted at 0.1 m into a 400 x 400 image. ``fls.frame_400`` takes the turn as one
sector; ``fls.frame_400_sectors`` as the node gets it, 40 sectors of 10 beams (each filtered and
painted as it comes, the image segmented once the turn completes).
"""
from __future__ import annotations

import math

import numpy as np

from sonar_tracking.cli.bench import Case, register


def _turn(sector_size: int):
    from sonar_tracking.sim import SimConfig, Simulator, Target
    from sonar_tracking.sim.motion import StaticTrajectory
    from sonar_tracking.sim.shapes import shape
    cfg = SimConfig.for_scenario('clutter', 'seaking675', sector_size=sector_size, **{
        'seaking.scan_min_deg': -180.0, 'seaking.scan_max_deg': 180.0, 'seaking.step_deg': 0.9,
        'seaking.range_max': 20.0, 'seaking.n_bins': 400})
    sim = Simulator(cfg, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    names = ('pontoon', 'cube', 'prism', 'reflector', 'sphere')
    for k in range(20):  # 20 targets on a spiral, 4 to 18 m out
        r, b = 4.0 + 0.7 * k, 2.0 * math.pi * k / 20
        sim.scene.targets.append(Target(k + 1, StaticTrajectory(r * math.cos(b), r * math.sin(b),
                                                                float(rng.uniform(0, 2 * math.pi))),
                                        shape(names[k % 5]), snr_db=25.0))
    sectors = []
    while True:
        s = sim.next_sector()
        sectors.append(s)
        if s.end_of_sweep:
            return sectors, cfg.seaking.sweep_time


def _frame(sector_size: int, settings: dict | None = None):
    from sonar_tracking.core.fls import FlsConfig, FlsProcessor
    sectors, period = _turn(sector_size)
    processor = FlsProcessor(FlsConfig.from_flat(settings or {}))
    clock = [0.0]

    def one_frame():
        frames = []
        for s in sectors:
            frames += processor.add_sector(s.amplitudes, s.geometry, s.pose, clock[0] + s.stamp)
        clock[0] += period
        return frames
    frames = one_frame()
    n = len(frames[-1].regions)
    if frames[-1].image.shape != (400, 400) or n != 20:
        raise RuntimeError(f'bench frame has {frames[-1].image.shape} pixels and {n} regions, not 400 x 400 and 20')
    return one_frame


register(Case(name='fls.frame_400', group='fls', make=lambda: _frame(400), limit_s=0.020, repeats=30,
              description='FLS frame 400 x 400: filter + paint + region growing + 30 features of 20 regions'))
register(Case(name='fls.frame_400_sectors', group='fls', make=lambda: _frame(10), repeats=20,
              description='the same frame as 40 sectors of 10 beams (as the node receives it)'))
register(Case(name='fls.frame_400_structure', group='fls', repeats=30, compare_to='fls.frame_400',
              make=lambda: _frame(400, {'structure.enabled': True, 'structure.max_length': 6.0,
                                        'structure.elongated_length': 3.0, 'structure.warmup': False}),
              description='fls.frame_400 with static-structure rejection: shape gates, persistent-echo '
                          'veto and learning on the 400 x 400 image (its 20 targets are static, so they '
                          'become structure and no features are computed; no warm-up, so the first frame '
                          'holds the 20 regions)'))

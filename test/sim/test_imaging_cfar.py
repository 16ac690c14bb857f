"""CFAR with each imaging preset's window on the simulator's noise-only frames (beam-pattern
correlation, range-dependent level, seabed onset, 8-bit log counts with cells below the gain
floor): the design false-alarm probability lies in the measured 99 % interval. (1e-5 takes 220
full Oculus frames, about 30 s: measured once, docs/experiments/2026-11-27-imaging-front-end.md; the
imaging study repeats it.)

Alarms come in clumps of correlated cells, so the interval is taken over independent frames (a
Student-t interval of the per-frame rate), not from a binomial count. At least 1,000 alarms are
expected per case.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats

from sonar_tracking.core.detection import DetectorConfig
from sonar_tracking.core.detection.cfar import Cfar
from sonar_tracking.core.intensity import decode, zero_floor
from sonar_tracking.io.param_files import parameters_for
from sonar_tracking.sim import SimConfig, Simulator

SENSORS = Path(__file__).resolve().parents[2] / 'config' / 'sensors'
PRESETS = {'oculus_m750d': 'oculus_m750d', 'gemini_720': 'gemini_720', 'aris3000': 'aris_didson'}


def preset_detector(sim_preset: str, **overrides) -> DetectorConfig:
    """The detector settings of the sensor's preset file (as active_detector reads them)."""
    data = yaml.safe_load((SENSORS / f'{PRESETS[sim_preset]}.yaml').read_text())
    known = DetectorConfig().flat()
    flat = {k: v for k, v in parameters_for(data, 'active_detector', '/').items() if k in known}
    return DetectorConfig.from_flat({**known, **flat, **overrides})


def measured_rate(sim_preset: str, design: float, frames: int, seed: int) -> tuple[float, float, float, int]:
    """Per-frame false-alarm rates of independent noise-only frames: mean, 99 % interval, alarms."""
    cfg = SimConfig.for_scenario('imaging_empty', sim_preset)
    # Another design rate than the preset's: its scale may lie below the preset's ESC floor.
    detector = preset_detector(sim_preset, **{'cfar.pfa': design, 'intensity.coding': 'db', 'threshold.minimum': 1.0,
                                              'intensity.db_span': cfg.output.db_span})
    cfar = Cfar(detector.threshold.method, detector.cfar)
    floor = zero_floor(detector.intensity, np.dtype(np.uint8)) ** 2
    rates, alarms = [], 0
    for k in range(frames):
        s = Simulator(cfg, np.random.default_rng([seed, k])).next_sector()
        amplitude = decode(s.amplitudes, 'db', db_span=cfg.output.db_span, full_scale=255.0)
        q = cfar.normalise(np.square(amplitude).astype(np.float32), floor)
        n = int(np.count_nonzero(q > cfar.alpha0))
        rates.append(n / np.count_nonzero(np.isfinite(q)))
        alarms += n
    mean = float(np.mean(rates))
    half = stats.t.ppf(0.995, frames - 1) * np.std(rates, ddof=1) / math.sqrt(frames)
    return mean, mean - half, mean + half, alarms


@pytest.mark.parametrize('sim_preset,design,frames', [
    ('oculus_m750d', 1e-3, 12), ('gemini_720', 1e-3, 12), ('aris3000', 1e-3, 12), ('oculus_m750d', 1e-4, 24)])
def test_the_presets_cfar_holds_its_design_pfa_on_simulated_frames(sim_preset, design, frames):
    mean, lo, hi, alarms = measured_rate(sim_preset, design, frames, seed=31)
    assert alarms >= 1000 * 0.8, alarms            # about 1,000 expected
    assert lo <= design <= hi, (mean, lo, hi)

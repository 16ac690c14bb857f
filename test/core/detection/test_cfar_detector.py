"""The active detector with a CFAR threshold method: the design false-alarm rate per cell, the
scale as the threshold ESC moves, targets found where they are."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
from sonar_tracking.core.detection.cfar import Cfar
from sonar_tracking.core.sector import SectorGeometry

GEOMETRY = SectorGeometry(range_min=1.0, range_max=40.0, n_bins=200, angle_min=-0.6, angle_increment=1.2 / 255,
                          n_beams=256)


def _config(method: str, pfa: float = 1e-3, esc: bool = False) -> DetectorConfig:
    base = DetectorConfig()
    return DetectorConfig.from_flat({**base.flat(), 'threshold.method': method, 'cfar.pfa': pfa,
                                     'esc.enabled': esc, 'cells.max_detections': 100_000})


@pytest.mark.parametrize('method', ['ca', 'go'])
def test_false_detections_per_frame_follow_the_design_pfa(method):
    """Rayleigh amplitude (exponential intensity) at levels 20 dB apart from frame to frame: each cell
    is a detection with the design probability; ESC off keeps the scale at its design value."""
    rng = np.random.default_rng(21)
    det = ActiveDetector(_config(method))
    total = cells = 0
    for k in range(30):
        level = 10.0 ** (2 * (k % 3))
        amplitude = np.sqrt(level * rng.standard_exponential(GEOMETRY.shape)).astype(np.float32)
        result = det.process(amplitude, GEOMETRY, stamp=float(k))
        assert result.threshold == pytest.approx(det.cfar.alpha0)
        total += len(result.detections)
        cells += int(np.count_nonzero(np.isfinite(det.cfar.normalise(np.square(amplitude)))))   # tested: not corners
    lo = stats.beta.ppf(0.005, total, cells - total + 1)
    hi = stats.beta.ppf(0.995, total + 1, cells - total)
    assert lo <= 1e-3 <= hi, (total, cells)


def test_a_target_is_found_at_its_cell_with_its_amplitude():
    rng = np.random.default_rng(22)
    det = ActiveDetector(_config('ca', 1e-5))
    amplitude = np.sqrt(rng.standard_exponential(GEOMETRY.shape)).astype(np.float32)
    amplitude[120, 100] = 30.0          # intensity 900: about 30 dB over the clutter
    result = det.process(amplitude, GEOMETRY, stamp=0.0)
    d = result.detections[np.argmax(result.detections['amplitude'])]
    assert d['amplitude'] == pytest.approx(30.0)
    r = GEOMETRY.range_min + 120 * GEOMETRY.range_resolution
    b = GEOMETRY.angle_min + 100 * GEOMETRY.angle_increment
    assert d['range'] == pytest.approx(r) and d['bearing'] == pytest.approx(b)


def test_esc_moves_the_scale_and_a_reset_returns_it_to_the_design_value():
    rng = np.random.default_rng(23)
    cfg = _config('ca', 1e-3, esc=True)
    # Far more false detections than desired: ESC raises the scale.
    cfg = DetectorConfig.from_flat({**cfg.flat(), 'esc.desired_clutter_density': 1e-4})
    det = ActiveDetector(cfg)
    alpha0 = det.threshold
    for k in range(40):
        amplitude = np.sqrt(rng.standard_exponential(GEOMETRY.shape)).astype(np.float32)
        det.process(amplitude, GEOMETRY, stamp=float(k))
    assert det.threshold > 1.2 * alpha0
    det.reset()
    assert det.threshold == pytest.approx(alpha0)


def test_a_design_pfa_whose_scale_lies_outside_the_threshold_bounds_is_refused():
    with pytest.raises(ConfigError, match=r'cfar\.pfa = 1e-12 .*threshold\.minimum'):
        DetectorConfig.from_flat({**DetectorConfig().flat(), 'threshold.method': 'ca', 'cfar.pfa': 1e-12})
    fixed = DetectorConfig.from_flat({**DetectorConfig().flat(), 'cfar.pfa': 1e-12})   # not used: accepted
    assert fixed.threshold.method == 'fixed'


def test_the_fixed_method_is_unchanged_by_the_cfar_settings():
    rng = np.random.default_rng(24)
    amplitude = rng.exponential(1.0, GEOMETRY.shape).astype(np.float32)
    a = ActiveDetector(_config('fixed')).process(amplitude, GEOMETRY, stamp=0.0)
    other = dataclasses.replace(_config('fixed'), cfar=dataclasses.replace(_config('fixed').cfar, reach_bins=20))
    b = ActiveDetector(other).process(amplitude, GEOMETRY, stamp=0.0)
    assert np.array_equal(a.detections, b.detections) and a.threshold == 3.0
    assert math.isclose(Cfar('ca', _config('ca').cfar).alpha0, ActiveDetector(_config('ca')).threshold)


def test_esc_with_a_period_updates_once_every_period_scans_on_their_mean_density():
    """esc.period 5: the threshold holds for five scans, then moves once, on the mean of their densities:
    the same step the controller takes when fed that mean directly."""
    from sonar_tracking.core.detection.esc import ExtremumSeekingController
    rng = np.random.default_rng(25)
    flat = {**_config('ca', 1e-3, esc=True).flat(), 'esc.period': 5, 'esc.desired_clutter_density': 1e-4}
    det = ActiveDetector(DetectorConfig.from_flat(flat))
    e = det.config.esc
    ref = ExtremumSeekingController(1e-4, det.threshold, det.config.threshold.minimum,
                                    det.config.threshold.maximum, e.dither_amplitude, e.dither_decay, e.gain)
    applied, densities = [], []
    for k in range(15):
        amplitude = np.sqrt(rng.standard_exponential(GEOMETRY.shape)).astype(np.float32)
        result = det.process(amplitude, GEOMETRY, stamp=float(k))
        applied.append(result.threshold)
        densities.append(result.mean_density)
        if (k + 1) % 5 == 0:
            ref.update(float(np.mean(densities[-5:])))
            assert det.threshold == pytest.approx(ref.threshold)
    assert len(set(applied[0:5])) == len(set(applied[5:10])) == len(set(applied[10:15])) == 1
    assert applied[5] != applied[0] and applied[10] != applied[5]


@pytest.mark.parametrize('max_detections', [100, 1])
def test_over_cells_a_detection_near_the_head_gets_the_denser_clutter(max_detections):
    """Two echoes, at 5 m and 35 m: over area both get the same density (the count over the fan's
    area); over cells, the near one's is seven times the far one's, also when the strongest are cut."""
    amplitude = np.ones(GEOMETRY.shape, np.float32)
    rows = [int(round((r - GEOMETRY.range_min) / GEOMETRY.range_resolution)) for r in (5.0, 35.0)]
    amplitude[rows[0], 60] = amplitude[rows[1], 180] = 30.0
    amplitude[rows[1], 180] = 31.0
    rho = {}
    for over in ('area', 'cells'):
        cfg = DetectorConfig.from_flat({**_config('fixed').flat(), 'threshold.initial': 10.0,
                                        'cells.max_detections': max_detections, 'scmde.uniform_over': over})
        d = ActiveDetector(cfg).process(amplitude, GEOMETRY, stamp=0.0).detections
        assert len(d) == min(2, max_detections)
        rho[over] = dict(zip(np.round(d['range']).astype(int), d['clutter_density']))
    if max_detections > 1:
        assert rho['area'][5] == pytest.approx(rho['area'][35])
        assert rho['cells'][5] / rho['cells'][35] == pytest.approx(35 / 5, rel=0.02)
    assert rho['cells'][35] < rho['area'][35]

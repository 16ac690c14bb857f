"""CFAR: the false-alarm formulas against simulation, the design P_fa held at every cell (edges and
no-data cells included), under level changes and with correlated beams."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from scipy.signal import fftconvolve

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.detection.cfar import Cfar, CfarConfig, design_scale, pfa


def _interval(alarms: int, trials: int, level: float = 0.99) -> tuple[float, float]:
    """Clopper-Pearson interval of a binomial proportion."""
    a = 1.0 - level
    lo = stats.beta.ppf(a / 2, alarms, trials - alarms + 1) if alarms else 0.0
    hi = stats.beta.ppf(1 - a / 2, alarms + 1, trials - alarms)
    return float(lo), float(hi)


@pytest.mark.parametrize('method,n,rank', [('ca', 16, 0), ('go', 8, 0), ('os', 16, 12), ('os', 24, 18)])
def test_the_pfa_formulas_match_independent_exponential_cells(method, n, rank):
    rng = np.random.default_rng(11)
    alpha = design_scale(method, n, 0.01, rank)
    assert pfa(method, n, alpha, rank) == pytest.approx(0.01, rel=1e-9)
    trials = 300_000
    if method == 'ca':
        z = rng.standard_exponential((trials, n)).mean(axis=1)
    elif method == 'go':
        z = np.maximum(rng.standard_exponential((trials, n)).mean(axis=1),
                       rng.standard_exponential((trials, n)).mean(axis=1))
    else:
        z = np.sort(rng.standard_exponential((trials, n)), axis=1)[:, rank - 1]
    alarms = int(np.count_nonzero(rng.standard_exponential(trials) > alpha * z))
    lo, hi = _interval(alarms, trials)
    assert lo <= 0.01 <= hi, (alarms, lo, hi)


def test_the_scales_are_ordered_as_the_theory_says():
    # Greatest-of pays for its robustness at edges with a higher scale than cell averaging of the
    # same cells; more training cells need a lower scale.
    assert design_scale('ca', 32, 1e-4) > design_scale('ca', 64, 1e-4)
    assert design_scale('go', 16, 1e-4) / 16 < design_scale('ca', 16, 1e-4) / 16
    assert design_scale('ca', 10_000, 1e-4) == pytest.approx(-math.log(1e-4), rel=1e-3)   # known level


def _count(cfar: Cfar, frames, alpha: float | None = None) -> tuple[int, int]:
    alarms = tested = 0
    for p in frames:
        q = cfar.normalise(p)
        alarms += int(np.count_nonzero(q > (alpha or cfar.alpha0)))
        tested += int(np.count_nonzero(np.isfinite(q)))
    return alarms, tested


def _exponential_frames(rng, n, shape=(300, 256), zeros=0.0, level=None):
    for _ in range(n):
        p = rng.standard_exponential(shape).astype(np.float32)
        if level is not None:
            p *= level
        if zeros:
            p[rng.random(shape) < zeros] = 0.0
        yield p


@pytest.mark.parametrize('method,design', [('ca', 1e-3), ('ca', 1e-4), ('go', 1e-3), ('go', 1e-4), ('os', 1e-3)])
def test_the_design_pfa_holds_at_every_cell_edges_and_no_data_included(method, design):
    """At least 1,000 expected alarms per case; 10 % of the cells are no data, and the frame's edges
    (short windows) count: the design value lies in the measured 99 % interval."""
    rng = np.random.default_rng(12 if design == 1e-3 else 13)
    cfar = Cfar(method, CfarConfig(pfa=design))
    shape = (300, 256)
    n_frames = math.ceil(1000 / (design * 0.9 * shape[0] * shape[1])) if method != 'os' else None
    if method == 'os':      # rank filtering is slow: a smaller window and fewer, larger counts
        cfar = Cfar(method, CfarConfig(pfa=design, reach_bins=6, reach_beams=6))
        n_frames = math.ceil(1000 / (design * 0.9 * shape[0] * shape[1]))
    alarms, tested = _count(cfar, _exponential_frames(rng, n_frames, shape, zeros=0.1))
    lo, hi = _interval(alarms, tested)
    assert lo <= design <= hi, (alarms, tested, lo, hi)


@pytest.mark.parametrize('method', ['ca', 'go'])
def test_the_pfa_does_not_depend_on_the_clutter_level(method):
    """Two clutter levels 20 dB apart in the same frame (bands of range): away from the step, the
    false-alarm rate is the design value on both sides; greatest-of also holds it at the step."""
    rng = np.random.default_rng(14)
    design = 1e-3
    cfar = Cfar(method, CfarConfig(pfa=design))
    level = np.where(np.arange(300) < 150, 1.0, 100.0).astype(np.float32)[:, None]
    alarms_far = tested_far = 0
    for p in _exponential_frames(rng, 16, level=level):
        q = cfar.normalise(p)
        for band in (slice(20, 130), slice(170, 280)):
            alarms_far += int(np.count_nonzero(q[band] > cfar.alpha0))
            tested_far += int(np.count_nonzero(np.isfinite(q[band])))
    lo, hi = _interval(alarms_far, tested_far)
    assert lo <= design <= hi


def _correlated_frames(rng, n, shape=(300, 512), oversampling=4):
    """Speckle of a beamformer that forms ``oversampling`` beams per beam width: a complex white field
    convolved across beams with a sinc amplitude response, normalised to unit power."""
    k = np.arange(-6 * oversampling, 6 * oversampling + 1)
    h = np.sinc(k / oversampling)
    h /= np.sqrt(np.sum(h * h))
    for _ in range(n):
        w = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / math.sqrt(2.0)
        z = fftconvolve(w, h[None, :], mode='same', axes=1)
        yield (np.abs(z) ** 2).astype(np.float32)


def test_correlated_beams_need_a_stride_of_one_beam_width():
    """Four beams per beam width: training cells one beam apart are correlated and cell averaging
    exceeds its design value; a stride of four beams (one beam width) restores it."""
    design = 1e-3
    rng = np.random.default_rng(15)
    dense = Cfar('ca', CfarConfig(pfa=design, guard_beams=4, reach_beams=16, stride_beams=1, stride_bins=1,
                                  guard_bins=1, reach_bins=3))
    strided = Cfar('ca', CfarConfig(pfa=design, guard_beams=4, reach_beams=32, stride_beams=4, stride_bins=1,
                                    guard_bins=1, reach_bins=3))
    frames = list(_correlated_frames(rng, 8))
    alarms, tested = _count(dense, frames)
    assert _interval(alarms, tested)[0] > 1.2 * design          # too many alarms
    # Alarms come in clumps of correlated cells: count per frame and take the spread across frames.
    rates = [_count(strided, [f])[0] / _count(strided, [f])[1] for f in _correlated_frames(rng, 24)]
    mean, sem = np.mean(rates), np.std(rates, ddof=1) / math.sqrt(len(rates))
    assert abs(mean - design) < 3.0 * sem + 0.05 * design, (mean, sem)


def test_a_target_is_found_and_its_own_echo_is_guarded():
    rng = np.random.default_rng(16)
    p = rng.standard_exponential((120, 120)).astype(np.float32)
    p[60:62, 60:62] = 200.0                        # a 2 x 2 cell echo, 23 dB over the clutter
    for method in ('ca', 'go', 'os'):
        cfar = Cfar(method, CfarConfig(pfa=1e-4, reach_bins=8, reach_beams=8))
        q = cfar.normalise(p)
        assert (q[60:62, 60:62] > cfar.alpha0).all(), method


def test_settings_are_checked():
    with pytest.raises(ConfigError, match='cfar window'):
        CfarConfig(guard_bins=3, reach_bins=2)
    with pytest.raises(ConfigError, match='training cells'):
        CfarConfig(guard_bins=0, guard_beams=0, reach_bins=1, reach_beams=0, stride_bins=1)
    with pytest.raises(ConfigError, match='more than 1000'):     # bounded work per frame and at start
        CfarConfig(reach_bins=400, reach_beams=400, stride_bins=1, stride_beams=1)
    with pytest.raises(ConfigError):
        Cfar('median', CfarConfig())


def test_cells_below_the_sensors_floor_keep_the_design_pfa():
    """8-bit dB counts of speckle whose mean lies just above the gain floor: 4 cells in 10 read 0.
    With the floor the level comes from the measured cells' excess over it and the design rate
    holds per cell; their plain mean is too high and gives far fewer alarms than designed."""
    from sonar_tracking.core.intensity import IntensityConfig, decode, encode_db, zero_floor
    rng = np.random.default_rng(17)
    design = 1e-3
    cfar = Cfar('ca', CfarConfig(pfa=design))
    floor = zero_floor(IntensityConfig(coding='db', db_span=60.0), np.dtype(np.uint8)) ** 2
    counts = dict.fromkeys(('excess', 'plain'), (0, 0))
    zeros = []
    for _ in range(12):
        power = rng.standard_exponential((300, 256))
        amplitude = decode(encode_db(np.sqrt(power), 60.0, 255, reference=0.7), 'db', db_span=60.0, full_scale=255.0)
        p = np.square(amplitude).astype(np.float32)
        zeros.append(np.mean(p == 0))
        for name, f in (('excess', floor), ('plain', 0.0)):
            q = cfar.normalise(p, f)
            tested = np.isfinite(q) if f else np.isfinite(q) | (p == 0)    # every cell counts
            a, n = counts[name]
            counts[name] = (a + int(np.count_nonzero(q > cfar.alpha0)), n + int(np.count_nonzero(tested)))
    assert 0.35 < np.mean(zeros) < 0.45
    lo, hi = _interval(*counts['excess'])
    assert lo <= design <= hi, counts
    assert _interval(*counts['plain'])[1] < 0.7 * design, counts

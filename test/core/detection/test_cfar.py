"""CFAR: the false-alarm formulas against simulation, the design P_fa held at every cell (edges and
no-data cells included), under level changes and with correlated beams; the compiled CA
normalisation against the array formula, bit for bit."""
from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
from scipy import stats
from scipy.signal import fftconvolve

from sonar_tracking.core.background import measured, window_sums
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


def _normalised(cfar: Cfar, power: np.ndarray, floor: float) -> np.ndarray:
    """``q = P / (Z c)`` from the level and ratio :meth:`Cfar.level` gives, in numpy's arithmetic
    (float32 level, float64 scale and quotient), NaN where not tested."""
    p = np.asarray(power, np.float32)
    z, ratio = cfar.level(p, floor)
    with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
        denom = z * ratio
        tested = np.isfinite(denom) & (denom > 0) & (measured(p) | (floor > 0) & np.isfinite(p))
        return np.where(tested, p / np.where(tested, denom, 1.0), np.nan).astype(np.float32)


def test_the_compiled_ca_normalisation_equals_the_array_formula_bit_for_bit():
    """Random windows, design P_fa and min_train on frames with no-data cells (0, NaN, inf), with and
    without a floor: the one-pass normalisation gives every cell the array formula's value exactly,
    and NaN where that leaves the cell untested."""
    from sonar_tracking.core.detection.cfar import _ca_normalise
    rng = np.random.default_rng(41)
    checked = 0
    while checked < 40:
        cfg = CfarConfig(pfa=float(rng.choice([1e-3, 1e-5])), guard_bins=int(rng.integers(0, 4)),
                         guard_beams=int(rng.integers(0, 7)), reach_bins=int(rng.integers(4, 12)),
                         reach_beams=int(rng.integers(7, 25)), stride_bins=int(rng.integers(1, 3)),
                         stride_beams=int(rng.integers(1, 5)), min_train=float(rng.choice([0.3, 0.5, 0.9])))
        try:
            cfar = Cfar('ca', cfg)
        except (ConfigError, ValueError):
            continue
        shape = (int(rng.integers(1, 70)), int(rng.integers(1, 70)))
        p = rng.standard_exponential(shape).astype(np.float32)
        p[rng.random(shape) < 0.2] = 0.0
        p[rng.random(shape) < 0.03] = np.nan
        p[rng.random(shape) < 0.03] = np.inf
        for floor in (0.0, 0.01):
            expected = _normalised(cfar, p, floor)
            assert np.array_equal(cfar.normalise(p, floor), expected, equal_nan=True), (cfg, shape, floor)
            sums = window_sums(p, cfar.window, floor=floor)
            q = np.empty(shape, np.float32)
            _ca_normalise(np.ascontiguousarray(p), sums.total, sums.count, cfar._ratio, floor, q)
            assert np.array_equal(q, expected, equal_nan=True)
        checked += 1


def test_an_imaging_frame_is_normalised_without_frame_sized_float64_temporaries():
    """The Oculus preset's CA-CFAR on a 512-beam x 1000-bin frame allocates the window sums and the
    result, float32 (the array formula makes float64 levels, scales and quotients of the frame)."""
    cfar = Cfar('ca', CfarConfig(pfa=1e-5, guard_bins=3, guard_beams=6, reach_bins=11, reach_beams=24,
                                 stride_bins=2, stride_beams=4))
    rng = np.random.default_rng(43)
    p = rng.standard_exponential((1000, 512)).astype(np.float32)
    p[rng.random(p.shape) < 0.1] = 0.0
    expected = _normalised(cfar, p, 0.01)
    cfar.normalise(p, 0.01)
    tracemalloc.start()
    try:
        q = cfar.normalise(p, 0.01)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert np.array_equal(q, expected, equal_nan=True)
    assert np.count_nonzero(q > cfar.alpha0) < 100      # speckle: the design rate, a handful of cells
    assert peak < 3 * p.nbytes + 2 ** 19, peak

"""The local-background rule: training windows, their sums, counts and order statistics, checked
against a direct loop over each cell's training cells; the compiled whole-window sums against
OpenCV's separable filter, bit for bit."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from sonar_tracking.core import background
from sonar_tracking.core.background import (
    Window,
    exponential_order_mean,
    measured,
    range_profile,
    window_order,
    window_sums,
)

WINDOWS = [Window(1, 2, 4, 6, 1, 2), Window(2, 2, 6, 6, 2, 2), Window(0, 3, 5, 3, 1, 1), Window(3, 0, 3, 9, 3, 3)]


def _direct(power: np.ndarray, window: Window):
    """Per cell: measured training values, and those of the nearer half, by a plain loop."""
    rb, rw = window.reach_bins, window.reach_beams
    offsets = np.argwhere(window.footprint) - [rb, rw]
    nearer = {tuple(o) for o in np.argwhere(window.nearer) - [rb, rw]}
    rows, cols = power.shape
    out = {}
    for y in range(rows):
        for x in range(cols):
            cells, near, missing = [], [], 0
            for i, j in offsets:
                yy, xx = y + i, x + j
                v = power[yy, xx] if 0 <= yy < rows and 0 <= xx < cols else 0.0
                if v == 0 or not np.isfinite(v):
                    missing += 1
                    continue
                cells.append(v)
                if (i, j) in nearer:
                    near.append(v)
            out[y, x] = (cells, near, missing)
    return out


@pytest.mark.parametrize('window', WINDOWS, ids=str)
def test_window_sums_and_counts_equal_a_direct_loop(window):
    rng = np.random.default_rng(5)
    p = rng.standard_exponential((23, 31)).astype(np.float32)
    p[rng.random(p.shape) < 0.2] = 0.0          # no data
    p[3, 4] = np.nan
    direct = _direct(p, window)
    sums = window_sums(p, window, halves=True)
    for (y, x), (cells, near, _) in direct.items():
        assert sums.count[y, x] == len(cells)
        assert sums.near_count[y, x] == len(near)
        assert sums.total[y, x] == pytest.approx(sum(cells), rel=1e-5, abs=1e-4)
        assert sums.near_total[y, x] == pytest.approx(sum(near), rel=1e-5, abs=1e-4)
    assert np.count_nonzero(window.nearer) * 2 == window.size      # the halves are mirror images


@pytest.mark.parametrize('window', WINDOWS[:2], ids=str)
def test_window_order_is_the_rank_among_training_cells_with_missing_ones_first(window):
    rng = np.random.default_rng(6)
    p = rng.standard_exponential((19, 27)).astype(np.float32)
    p[rng.random(p.shape) < 0.15] = 0.0
    rank = max(1, window.size * 3 // 4)
    stat, missing = window_order(p, window, rank)
    for (y, x), (cells, _, m) in _direct(p, window).items():
        assert missing[y, x] == m
        values = sorted([0.0] * m + cells)
        assert stat[y, x] == pytest.approx(values[rank - 1], rel=1e-6)


def test_full_frames_take_their_counts_from_the_cache_and_agree():
    w = Window(2, 2, 8, 8, 2, 2)
    p = np.random.default_rng(7).standard_exponential((40, 50)).astype(np.float32)
    full = window_sums(p, w)
    q = p.copy()
    q[0, 0] = 0.0                                  # one unmeasured cell: counted the long way
    partial = window_sums(q, w)
    far = (slice(20, 40), slice(20, 50))           # cells whose windows do not reach (0, 0)
    assert np.array_equal(full.count[far], partial.count[far])
    assert full.count[25, 25] == w.size


def test_measured_and_order_means():
    assert measured(np.array([0.0, np.nan, np.inf, 1.0, -2.0])).tolist() == [False, False, False, True, True]
    assert exponential_order_mean(1, 1) == 1.0
    assert exponential_order_mean(3, 3) == pytest.approx(1 + 1 / 2 + 1 / 3)
    assert exponential_order_mean(10001, 5001) == pytest.approx(np.log(2.0), abs=1e-4)   # the median
    with pytest.raises(ValueError):
        exponential_order_mean(4, 5)


def test_a_window_without_training_cells_is_refused():
    with pytest.raises(ValueError):
        Window(3, 3, 3, 3, 1, 1)
    with pytest.raises(ValueError):
        Window(4, 1, 3, 3, 1, 1)


def test_range_profile_is_the_speckle_mean_per_bin():
    rng = np.random.default_rng(8)
    level = np.linspace(1.0, 10.0, 200)[:, None]
    p = level * rng.standard_exponential((200, 400))
    ratio = range_profile(p, 1)[:, ] / level[:, 0]
    assert abs(np.median(ratio) - 1.0) < 0.03


# -- the compiled whole-window sums ------------------------------------------------------------------

#: The Oculus M750d preset's CA-CFAR window (config/sensors/oculus_m750d.yaml).
OCULUS = Window(guard_bins=3, guard_beams=6, reach_bins=11, reach_beams=24, stride_bins=2, stride_beams=4)


def _filter_sums(power: np.ndarray, window: Window, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """The whole window's sums and counts by OpenCV's separable filter (:meth:`Window.correlate`) on
    the measured cells' excess over ``floor`` and on the measured-cell marks."""
    p = np.asarray(power, np.float32)
    ok = np.isfinite(p) & (p != 0)
    values = np.where(ok, np.maximum(p - np.float32(floor), np.float32(0.0)) if floor > 0 else p, np.float32(0.0))
    total = np.maximum(window.correlate(values.astype(np.float32)), np.float32(0.0))
    return total, np.rint(window.correlate(ok.astype(np.float32)))


def _kernel_sums(power: np.ndarray, window: Window, floor: float) -> tuple[np.ndarray, np.ndarray]:
    p = np.ascontiguousarray(power, np.float32)
    total, count = np.empty(p.shape, np.float32), np.empty(p.shape, np.float32)
    background._ca_sums(p, float(floor), *window.sum_plan, total, count)
    return total, count


def _random_windows(n: int, seed: int) -> list[Window]:
    """``n`` windows of every kind: strides 1-5, guards 0-4, reaches up to 16 x 30 (short row kernels
    of up to 5 taps included, which OpenCV adds in another order)."""
    rng = np.random.default_rng(seed)
    out: list[Window] = []
    while len(out) < n:
        gb, gw = (int(v) for v in rng.integers(0, 5, 2))
        sb, sw = (int(v) for v in rng.integers(1, 6, 2))
        try:
            out.append(Window(gb, gw, gb + int(rng.integers(0, 13)), gw + int(rng.integers(0, 27)), sb, sw))
        except ValueError:
            continue
    return out


@pytest.mark.parametrize('window', _random_windows(40, 21) + [OCULUS], ids=str)
def test_the_compiled_sums_equal_the_separable_filter_bit_for_bit(window):
    """Every cell's sum and count, for frames with no-data cells (0, NaN, inf), with and without a
    floor, smaller and larger than the window, equal OpenCV's exactly (float32 sums depend on the
    order of their additions)."""
    rng = np.random.default_rng([window.guard_bins, window.guard_beams, window.reach_bins, window.reach_beams,
                                 window.stride_bins, window.stride_beams])
    for shape in ((1, 1), (1, 37), (29, 1), (int(rng.integers(2, 12)), int(rng.integers(2, 12))), (61, 83)):
        p = (rng.standard_exponential(shape) * rng.choice([1e-3, 1.0, 1e3], shape)).astype(np.float32)
        p[rng.random(shape) < 0.25] = 0.0
        p[rng.random(shape) < 0.03] = np.nan
        p[rng.random(shape) < 0.02] = np.inf
        for floor in (0.0, 0.2):
            total, count = _kernel_sums(p, window, floor)
            ref_total, ref_count = _filter_sums(p, window, floor)
            assert np.array_equal(total, ref_total) and np.array_equal(count, ref_count), (shape, floor)
            sums = window_sums(p, window, floor=floor)
            assert np.array_equal(sums.total, ref_total) and np.array_equal(sums.count, ref_count)


def test_an_imaging_frame_takes_the_compiled_sums_without_frame_sized_temporaries():
    """A 512-beam x 1000-bin frame with the Oculus window: window_sums equals the filter's sums and
    allocates its two results and a few rows (the filter's way makes about a dozen frame-sized
    arrays)."""
    rng = np.random.default_rng(31)
    p = rng.standard_exponential((1000, 512)).astype(np.float32)
    p[rng.random(p.shape) < 0.1] = 0.0
    ref_total, ref_count = _filter_sums(p, OCULUS, 0.01)
    window_sums(p, OCULUS, floor=0.01)   # compiled (or loaded) before measuring
    tracemalloc.start()
    try:
        sums = window_sums(p, OCULUS, floor=0.01)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert np.array_equal(sums.total, ref_total) and np.array_equal(sums.count, ref_count)
    assert peak < 2 * p.nbytes + 2 ** 19, peak

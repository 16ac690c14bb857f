"""The local-background rule: training windows, their sums, counts and order statistics, checked
against a direct loop over each cell's training cells."""
from __future__ import annotations

import numpy as np
import pytest

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

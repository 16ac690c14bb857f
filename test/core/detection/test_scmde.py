"""SCMDE: unbiased on homogeneous Poisson clutter, edge-corrected, with a count fallback; over area
or over the polar image's cells."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.detection import PolarWindow, scmde
from sonar_tracking.core.detection.scmde import DISC, RectWindow, cell_count_density, scmde_cells

WINDOW = PolarWindow(1800.0, 3300.0, math.radians(-2.0), math.radians(22.0))


def poisson_points(rho, rng, window=WINDOW):
    n = rng.poisson(rho * window.area)
    r = np.sqrt(rng.uniform(window.r_min ** 2, window.r_max ** 2, n))
    b = rng.uniform(window.b_min, window.b_max, n)
    return np.stack([r * np.cos(b), r * np.sin(b)], axis=1)


@pytest.mark.parametrize('rho', [2e-5, 1e-4, 5e-4])
def test_mean_estimate_within_ten_percent_of_the_true_density(rho):
    rng = np.random.default_rng(int(rho * 1e7))
    est = [scmde(poisson_points(rho, rng), 6, WINDOW) for _ in range(150)]
    mean = np.concatenate(est).mean()
    assert mean == pytest.approx(rho, rel=0.10)
    # Scan means, as ESC uses them, too.
    assert np.mean([e.mean() for e in est if len(e)]) == pytest.approx(rho, rel=0.10)


def test_without_edge_correction_the_border_biases_low():
    rng = np.random.default_rng(3)
    pts = [poisson_points(2e-5, rng) for _ in range(100)]
    corrected = np.concatenate([scmde(p, 6, WINDOW) for p in pts]).mean()
    raw = np.concatenate([scmde(p, 6, None) for p in pts]).mean()
    assert raw < 0.85 * 2e-5 < corrected


def test_nearest_neighbour_estimator_is_n_minus_one_over_volume():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [3.0, 0.0], [0.0, -4.0]])
    rho = scmde(pts, order=3)
    # Third nearest of the origin is at distance 3: (3 - 1) / (pi 3^2).
    assert rho[0] == pytest.approx(2.0 / (math.pi * 9.0))


def test_sparse_scans_use_the_count_estimate():
    pts = np.array([[2500.0, 100.0], [2600.0, 300.0]])
    assert scmde(pts, 6, WINDOW) == pytest.approx([2 / WINDOW.area] * 2)
    assert len(scmde(np.zeros((0, 2)), 6, WINDOW)) == 0


@pytest.mark.parametrize('kind', ['uniform', 'line', 'coincident', 'cluster_and_outlier', 'thin', 'far_from_origin'])
def test_nth_neighbour_distances_equal_a_kd_tree_query(kind):
    """The grid search returns exactly what scipy's KD-tree query returns, also on degenerate spreads."""
    from scipy.spatial import cKDTree

    from sonar_tracking.core.detection.scmde import _nth_neighbour
    rng = np.random.default_rng(len(kind))
    for m in (3, 8, 57, 600, 2500):
        if kind == 'uniform':
            p = rng.uniform(0, 3000, (m, 2))
        elif kind == 'line':
            p = np.column_stack([rng.uniform(0, 3000, m), np.full(m, 5.0)])
        elif kind == 'coincident':
            p = np.round(rng.normal(0, 3, (m, 2)))
        elif kind == 'cluster_and_outlier':
            p = np.concatenate([rng.normal(0, 0.01, (m - 1, 2)), [[1e4, 1e4]]])
        elif kind == 'thin':
            p = rng.uniform(-1, 1, (m, 2)) * [1e5, 1e-3]
        else:
            p = np.round(rng.uniform(0, 50, (m, 2))) * 0.1 + 1e6
        for n in sorted({2, 6, min(m - 1, 20)}):
            if n >= m:
                continue
            out = np.empty(m)
            _nth_neighbour(p, n, out)
            np.testing.assert_array_equal(out, cKDTree(p).query(p, k=n + 1)[0][:, n])


@pytest.mark.parametrize('b_min,span_deg', [(-2.0, 24.0), (170.0, 20.0), (-60.0, 200.0), (-180.0, 360.0),
                                            (10.0, 400.0)])
def test_window_holds_the_points_of_its_ranges_and_bearings(b_min, span_deg):
    """contains: range within [r_min, r_max] and bearing within the span (wrapped), away from the border;
    disc_fraction: the share of the sunflower points of a disc that contains holds."""
    w = PolarWindow(100.0, 900.0, math.radians(b_min), math.radians(b_min + span_deg))
    rng = np.random.default_rng(int(span_deg))
    r = rng.uniform(0.0, 1000.0, 4000)
    b = rng.uniform(-2 * math.pi, 2 * math.pi, 4000)
    off = np.remainder(b - w.b_min, 2 * math.pi)             # bearing past b_min, in [0, 2 pi)
    in_range = (r >= 100.0) & (r <= 900.0)
    in_bearing = (off <= w.b_max - w.b_min) | (w.b_max - w.b_min >= 2 * math.pi)
    clear = (np.abs(r - 100.0) > 1e-6) & (np.abs(r - 900.0) > 1e-6) & (np.minimum(off, 2 * math.pi - off) > 1e-9) & (
        np.abs(off - (w.b_max - w.b_min)) > 1e-9)
    got = w.contains(r * np.cos(b), r * np.sin(b))
    np.testing.assert_array_equal(got[clear], (in_range & in_bearing)[clear])
    x, y = r[:50] * np.cos(b[:50]), r[:50] * np.sin(b[:50])
    share = w.disc_fraction(x, y, np.full(50, 40.0))
    pts_x = x[:, None] + 40.0 * DISC[None, :, 0]
    pts_y = y[:, None] + 40.0 * DISC[None, :, 1]
    np.testing.assert_array_equal(share, w.contains(pts_x, pts_y).mean(axis=1))


@pytest.mark.parametrize('bad', [np.nan, np.inf, 1e308])
def test_points_that_are_not_finite_or_spread_past_floats_are_refused(bad):
    pts = np.random.default_rng(3).uniform(0, 100, (50, 2))
    pts[7, 1] = bad
    if bad == 1e308:
        pts[8, 1] = -1e308                      # a spread of 2e308 overflows
    with pytest.raises(ValueError, match='finite'):
        scmde(pts, 6, WINDOW)


# -- clutter uniform over cells -------------------------------------------------------------------

FAN = PolarWindow(0.3, 30.0, math.radians(-65.0), math.radians(65.0))


def cell_points(n, rng, window=FAN):
    """``n`` points uniform over range and bearing (a CFAR's false alarms), and their true density
    per m^2 (the count over range and bearing, over the range)."""
    r = rng.uniform(window.r_min, window.r_max, n)
    b = rng.uniform(window.b_min, window.b_max, n)
    return r, b, n / ((window.r_max - window.r_min) * (window.b_max - window.b_min)) / r


@pytest.mark.parametrize('n', [5, 40, 400])
def test_over_cells_the_mean_estimate_is_the_true_density_at_every_range(n):
    """Over area the density near the head comes out several times too low; over cells it is right
    near the head and far from it (mean of estimate over truth within 10 %)."""
    rng = np.random.default_rng(n)
    ratio, near_area = [], []
    for _ in range(4000 // n):
        r, b, truth = cell_points(n, rng)
        ratio.append(scmde_cells(r, b, 6, FAN, 0.3) / truth)
        near_area.append((scmde(np.stack([r * np.cos(b), r * np.sin(b)], axis=-1), 6, FAN) / truth)[r < 2.0])
    ratio = np.concatenate(ratio)
    assert ratio.mean() == pytest.approx(1.0, rel=0.10)
    near = np.concatenate(near_area).mean()
    if n == 5:     # fewer than order + 1: over area, the count over the fan's area
        assert near < 0.25
    elif n == 40:  # neighbourhoods reaching past where the density changes
        assert near < 0.8


def test_over_cells_a_sparse_scan_gets_the_count_over_range_and_bearing_at_its_range():
    r, b = np.array([1.0, 20.0]), np.array([0.1, -0.2])
    per_rb = 2 / ((FAN.r_max - FAN.r_min) * (FAN.b_max - FAN.b_min))
    assert scmde_cells(r, b, 6, FAN, 0.3) == pytest.approx([per_rb / 1.0, per_rb / 20.0])
    assert cell_count_density(2, r, FAN, 0.3) == pytest.approx([per_rb / 1.0, per_rb / 20.0])
    # Inside the floor the density stops growing.
    assert cell_count_density(2, np.array([0.01]), FAN, 0.3) == pytest.approx([per_rb / 0.3])
    with pytest.raises(ValueError):
        cell_count_density(2, r, FAN, 0.0)


def test_a_rectangle_holds_the_share_of_a_disc_inside_it():
    rect = RectWindow(0.0, 10.0, 0.0, 4.0)
    frac = rect.disc_fraction(np.array([5.0, 0.0, 5.0]), np.array([2.0, 0.0, 0.0]), np.array([1.0, 1.0, 1.0]))
    assert frac[0] == 1.0
    assert frac[1] == pytest.approx(0.25, abs=0.05) and frac[2] == pytest.approx(0.5, abs=0.05)
    assert rect.clearance(np.array([5.0, 1.0, 11.0]), np.array([2.0, 3.5, 2.0])) == pytest.approx([2.0, 0.5, 0.0])
    assert rect.area == 40.0

"""Cell thresholding and merging; converted measurements (ESC eqs. 8-10, Mo et al. 1998)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.detection import convert_measurements, threshold_cells


def test_every_cell_above_threshold_is_a_detection_without_merging():
    a = np.zeros((5, 6))
    a[1, 1], a[1, 2], a[4, 5] = 5.0, 4.0, 3.5
    d = threshold_cells(a, 3.0)
    assert sorted(zip(d.rows, d.cols, d.amplitude)) == [(1, 1, 5.0), (1, 2, 4.0), (4, 5, 3.5)]
    assert len(threshold_cells(a, 5.0)) == 0  # strictly above


def test_cells_of_one_resolution_cell_merge_to_a_weighted_centroid():
    a = np.zeros((8, 8))
    a[2, 2], a[2, 3], a[3, 3] = 6.0, 3.0, 3.0   # one echo spread over neighbours
    a[6, 6] = 4.0                               # another, far away
    d = threshold_cells(a, 1.0, merge_bins=2, merge_beams=2)
    order = np.argsort(d.rows)
    assert len(d) == 2
    assert d.rows[order[0]] == pytest.approx((2 * 9 + 3 * 3) / 12) and d.cols[order[0]] == pytest.approx((2 * 6 + 3 * 6) / 12)
    assert d.amplitude[order[0]] == 6.0 and (d.rows[order[1]], d.cols[order[1]]) == (6, 6)
    # Two cells a full resolution cell apart stay separate.
    b = np.zeros((8, 8))
    b[2, 2] = b[2, 4] = 5.0
    assert len(threshold_cells(b, 1.0, merge_bins=2, merge_beams=2)) == 2


def jacobian_covariance(r, b, sr, sb):
    j = np.array([[math.cos(b), -r * math.sin(b)], [math.sin(b), r * math.cos(b)]])
    return j @ np.diag([sr * sr, sb * sb]) @ j.T


def test_linearized_conversion_is_eq8_to_10_with_the_sensor_pose():
    rng = np.random.default_rng(0)
    r, b = rng.uniform(100, 3000, 20), rng.uniform(-1, 1, 20)
    pose = (-2000.0, 30.0, 0.3)
    xy, cov = convert_measurements(r, b, 5.0, math.radians(0.1), pose)
    for k in range(20):
        bw = b[k] + pose[2]
        assert xy[k] == pytest.approx([pose[0] + r[k] * math.cos(bw), pose[1] + r[k] * math.sin(bw)])
        assert cov[k] == pytest.approx(jacobian_covariance(r[k], bw, 5.0, math.radians(0.1)), rel=1e-12)


def test_unbiased_conversion_removes_the_bias_and_gives_the_conditional_mse():
    rng = np.random.default_rng(1)
    r0, b0, sr, sb = 1000.0, 0.7, 20.0, math.radians(15.0)
    n = 400_000
    r, b = r0 + sr * rng.standard_normal(n), b0 + sb * rng.standard_normal(n)
    truth = np.array([r0 * math.cos(b0), r0 * math.sin(b0)])
    biased, _ = convert_measurements(r, b, sr, sb)
    unbiased, _ = convert_measurements(r, b, sr, sb, unbiased=True)
    assert np.linalg.norm(biased.mean(0) - truth) > 20.0
    assert np.linalg.norm(unbiased.mean(0) - truth) < 1.0
    # Given one measurement, the truth is spread by the noise: R_u is the mean squared error of z_u.
    rm, bm = 1200.0, -0.4
    z, cov = convert_measurements(np.array([rm]), np.array([bm]), sr, sb, unbiased=True)
    rt, bt = rm - sr * rng.standard_normal(n), bm - sb * rng.standard_normal(n)
    err = z[0] - np.stack([rt * np.cos(bt), rt * np.sin(bt)], axis=1)
    mse = err.T @ err / n
    assert cov[0] == pytest.approx(mse, rel=0.02, abs=50.0)


def test_best_track_density_is_local():
    """Scenario 2: most clutter comes from the lam 0.8 region, so near a track in the lam 1.6 region
    ESC sees far less clutter than the sector mean."""
    from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
    from sonar_tracking.core.sim import SimConfig, Simulator
    sim = Simulator(SimConfig.for_scenario('scenario2'), np.random.default_rng(4))
    y50 = sim.truth(50.0)[1][0, 1]
    cfg = DetectorConfig.from_flat({'esc.enabled': False, 'esc.density_source': 'best_track'})
    local, sector = ActiveDetector(cfg), ActiveDetector(DetectorConfig.from_flat({'esc.enabled': False}))
    ratios = []
    for _ in range(20):
        s = sim.next_sector()
        focus = (500.0, y50 - 330.0)          # inside the light-clutter (lam 1.6) region
        a = local.process(s.amplitudes, s.geometry, s.pose, focus).mean_density
        b = sector.process(s.amplitudes, s.geometry, s.pose).mean_density
        ratios.append(a / b)
    assert np.median(ratios) < 0.3

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
    assert d.rows[order[0]] == pytest.approx((2 * 9 + 3 * 3) / 12)
    assert d.cols[order[0]] == pytest.approx((2 * 6 + 3 * 6) / 12)
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
    from sonar_tracking.sim import SimConfig, Simulator
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


def neighbour_components(mask, merge_bins, merge_beams):
    """Reference: components of cells at most merge - 1 apart in both directions (union-find)."""
    pts = list(zip(*np.nonzero(mask)))
    parent = list(range(len(pts)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i in range(len(pts)):
        for j in range(i):
            if abs(pts[i][0] - pts[j][0]) <= merge_bins - 1 and abs(pts[i][1] - pts[j][1]) <= merge_beams - 1:
                parent[root(i)] = root(j)
    return [root(i) for i in range(len(pts))]


@pytest.mark.parametrize('merge', [(3, 3), (1, 4), (4, 1), (5, 2), (2, 7), (1, 2)])
def test_any_merge_size_groups_cells_within_the_resolution_cell(merge):
    """Regression: merge sizes other than (1, 1) and (2, 2) raised 'structure dimensions must be equal
    to 3' in ndimage.label."""
    from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
    from sonar_tracking.core.sector import SectorGeometry
    rng = np.random.default_rng(sum(merge))
    a = np.where(rng.random((30, 40)) < 0.06, rng.uniform(4.0, 9.0, (30, 40)), 1.0)
    d = threshold_cells(a, 3.0, *merge)
    roots = neighbour_components(a > 3.0, *merge)
    assert len(d) == len(set(roots))
    # Same partition as the reference, and each detection at its cells' weighted centroid.
    assert len({(g, r) for g, r in zip(d.cell_group, roots)}) == len(d)
    w = a[d.cell_rows, d.cell_cols]
    for k in range(len(d)):
        on = d.cell_group == k
        assert d.rows[k] == pytest.approx(np.sum(w[on] * d.cell_rows[on]) / w[on].sum())
        assert d.amplitude[k] == w[on].max()
    g = SectorGeometry(angle_min=-0.3, angle_increment=0.015, n_beams=40, range_min=100.0, range_max=390.0, n_bins=30)
    cfg = DetectorConfig.from_flat({'cells.merge_bins': merge[0], 'cells.merge_beams': merge[1],
                                    'esc.enabled': False})
    assert len(ActiveDetector(cfg).process(a.astype(np.float32), g).detections) == len(d)


def test_connected_grouping_is_one_detection_per_connected_group():
    a = np.ones((12, 12))
    a[2:5, 2:4] = 5.0        # a 3 x 2 block
    a[5, 4] = 6.0            # touching it diagonally
    a[9, 9] = 4.0            # alone
    a[9, 11] = 4.0           # two columns away: not connected
    d = threshold_cells(a, 3.0, connected=True)
    assert len(d) == 3 and d.n_echoes == 3
    big = int(np.argmax(d.amplitude))
    assert (d.span_rows[big], d.span_cols[big], d.amplitude[big]) == (4, 3, 6.0)
    # The paper's cells: every cell alone, but the connected echoes are the same.
    cells = threshold_cells(a, 3.0)
    assert len(cells) == 9 and cells.n_echoes == 3 and (cells.span_rows == 1).all()


def test_covariance_of_a_group_is_uniform_over_its_extent():
    """A single cell keeps sigma_r exactly; a group spanning L bins gets (L dr)^2 / 12 (eqs. 8-10 with
    that W)."""
    from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
    from sonar_tracking.core.sector import SectorGeometry
    g = SectorGeometry(angle_min=-0.01, angle_increment=0.0002, n_beams=101, range_min=1000.0, range_max=1100.0,
                       n_bins=101)  # 1 m bins; the beam at column 50 points along x
    a = np.zeros(g.shape, np.float32)
    a[10:15, 50] = 5.0    # 5 bins deep
    a[60, 20] = 5.0       # a single cell
    det = ActiveDetector(DetectorConfig.from_flat({'cells.grouping': 'connected', 'esc.enabled': False}))
    d = det.process(a, g).detections
    deep = d[np.argmin(d['range'])]
    single = d[np.argmax(d['range'])]
    assert deep['range'] == pytest.approx(1012.0)
    assert deep['cov_xx'] == pytest.approx(5.0 ** 2 / 12.0, rel=1e-6)
    _, cov = convert_measurements(np.array([single['range']]), np.array([single['bearing']]), 1.0 / math.sqrt(12),
                                  0.0002 / math.sqrt(12))
    assert [single['cov_xx'], single['cov_xy'], single['cov_yy']] == \
        pytest.approx([cov[0, 0, 0], cov[0, 0, 1], cov[0, 1, 1]], rel=1e-12)

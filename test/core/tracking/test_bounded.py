"""Bounded work per scan (birth budget, tentative and pair caps, chunks), spatial duplicate screen, coverage."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.tracking import Coverage, ImmIpdaTracker, TrackerConfig, TrackingInputError, management
from sonar_tracking.core.tracking import tracker as tracker_module
from sonar_tracking.core.tracking.management import birth_measurements, duplicate_tracks, pair_budget


def config(**flat) -> TrackerConfig:
    return TrackerConfig.from_flat(flat)


def test_births_prefer_unexplained_then_low_density_then_order():
    unused = np.array([True, True, True, False, True, True])
    rho = np.array([1e-3, 1e-5, 1e-4, 1e-9, 1e-5, 1e-6])
    validated = np.array([5, 3])            # 5 is in some track's gate
    assert birth_measurements(unused, validated, rho, 10).tolist() == [0, 1, 2, 4, 5]   # budget not binding
    assert birth_measurements(unused, validated, rho, 3).tolist() == [1, 2, 4]
    assert birth_measurements(unused, validated, rho, 1).tolist() == [1]               # tie on rho: first
    assert birth_measurements(unused, validated, rho, 0).tolist() == []


def test_pair_budget_drops_tentative_with_most_candidates_first():
    counts = np.array([10, 50, 30, 40, 5])
    confirmed = np.array([False, False, True, False, True])
    assert not pair_budget(counts, confirmed, 135).any()
    assert pair_budget(counts, confirmed, 134).tolist() == [False, True, False, False, False]
    assert pair_budget(counts, confirmed, 40).tolist() == [True, True, False, True, False]
    assert pair_budget(counts, confirmed, 30).tolist() == [True, True, True, True, False]


def dense_duplicates(x, P, confirmed, ids, thr):
    """Reference: every (confirmed, other) pair tested with the full Mahalanobis distance."""
    drop = np.zeros(x.shape[1], dtype=bool)
    for i in np.flatnonzero(confirmed):
        for j in range(x.shape[1]):
            if i == j:
                continue
            diff = x[:, i] - x[:, j]
            if diff @ np.linalg.solve(P[:, :, i] + P[:, :, j], diff) < thr:
                keep_i = (confirmed[i] and not confirmed[j]) or (confirmed[i] == confirmed[j] and ids[i] < ids[j])
                drop[j if keep_i else i] = True
    return drop


@pytest.mark.parametrize('dense_up_to', [0, 10**9])
def test_duplicates_screened_spatially_equal_the_dense_test(monkeypatch, dense_up_to):
    monkeypatch.setattr(management, '_DENSE_DUPLICATES', dense_up_to)     # box screen / all pairs
    rng = np.random.default_rng(3)
    for trial in range(40):
        n = int(rng.integers(2, 120))
        x = np.concatenate([rng.uniform(-300, 300, (2, n)), rng.normal(0, 3, (2, n))])
        k = n // 3                                     # near-copies of some tracks
        x[:, :k] = x[:, n - k:] + rng.normal(0, 2, (4, k))
        A = rng.normal(0, 1, (4, 4, n)) * rng.uniform(0.5, 20, n)
        P = np.einsum('ijt,kjt->ikt', A, A) + np.eye(4)[..., None]
        confirmed = rng.random(n) < 0.5
        ids = rng.permutation(n) + 1
        got = duplicate_tracks(x, P, np.ones(n), confirmed, ids, 9.49)
        assert np.array_equal(got, dense_duplicates(x, P, confirmed, ids, 9.49)), trial


def test_a_flood_of_detections_is_bounded_and_keeps_working():
    """20,000 uniform detections per scan: tracks, pairs and the cost stay within the caps."""
    rng = np.random.default_rng(5)
    cfg = config(**{'init.max_per_scan': 300, 'track.max_tracks': 2000, 'track.max_pairs': 30_000})
    trk = ImmIpdaTracker(cfg)
    for k in range(6):
        z = rng.uniform(-500, 500, (20_000, 2))
        out = trk.step(float(k), z, None, np.full(len(z), 0.02))
        rep = trk.report
        assert rep.initiated <= 300 and len(out) <= 2000 and rep.n_pairs <= 30_000
        assert rep.initiated + rep.not_initiated == 20_000 or k > 0
    assert rep.pair_capped > 0 and rep.not_initiated > 0
    # Concentrated: every detection inside every gate; the pair cap holds.
    for k in range(6, 9):
        out = trk.step(float(k), rng.normal(0, 3, (20_000, 2)), None, np.full(20_000, 0.02))
        assert trk.report.n_pairs <= 30_000
    assert np.isfinite(out['x']).all()


def test_the_budget_does_not_bind_in_sparse_scans():
    """With fewer unused detections than the budget every one starts a track (the paper's rule)."""
    rng = np.random.default_rng(8)
    a, b = ImmIpdaTracker(), ImmIpdaTracker(config(**{'init.max_per_scan': 10_000_000,
                                                      'track.max_pairs': 1_000_000_000}))
    for k in range(15):
        z = rng.uniform(-1000, 1000, (40, 2))
        ra, rb = a.step(float(k), z), b.step(float(k), z)
        assert np.array_equal(ra, rb)
    assert a.report.initiated > 0


def test_chunked_update_equals_one_chunk(monkeypatch):
    rng = np.random.default_rng(11)
    scans = [rng.uniform(-300, 300, (400, 2)) for _ in range(6)]
    rho = np.full(400, 400 / 600 ** 2)
    ref = ImmIpdaTracker()
    outs = [ref.step(float(k), z, None, rho).copy() for k, z in enumerate(scans)]
    monkeypatch.setattr(tracker_module, '_CHUNK_PAIRS', 50)
    chunked = ImmIpdaTracker()
    for k, z in enumerate(scans):
        out = chunked.step(float(k), z, None, rho)
        assert np.array_equal(out['track_id'], outs[k]['track_id'])
        for f in ('x', 'y', 'vx', 'vy', 'existence', 'cov_xx', 'mode_cv'):
            np.testing.assert_allclose(out[f], outs[k][f], rtol=1e-10, atol=1e-12)
    assert chunked.report.n_pairs == ref.report.n_pairs > 50


def test_tracker_chunk_bounds_split_by_counts():
    cb = tracker_module._chunk_bounds
    assert cb(np.array([3, 3, 3, 3]), 6) == [0, 2, 4]
    assert cb(np.array([10, 1, 1]), 5) == [0, 1, 3]
    assert cb(np.zeros(0, dtype=int), 5) == [0, 0]


def test_coverage_window_wraps_bearings():
    cov = Coverage(x=10.0, y=0.0, heading=math.pi, range_min=5.0, range_max=100.0,
                   bearing_min=-0.5, bearing_max=0.5)
    pts = np.array([[-40.0, 10.0, 60.0, 8.0, -200.0, 10.0],
                    [0.0, 40.0, 0.0, 0.0, 0.0, -20.0]])
    # behind the heading (west of the sensor) inside; north, east, too near, too far, 45 deg off: outside
    assert cov.contains(pts).tolist() == [True, False, False, False, False, False]
    full = Coverage(0.0, 0.0, 0.0, 0.0, 50.0, -math.pi, math.pi)
    assert full.contains(np.array([[-30.0, 0.0, 60.0], [1.0, -49.0, 0.0]])).tolist() == [True, True, False]
    with pytest.raises(TrackingInputError):
        Coverage(0.0, 0.0, 0.0, 10.0, 5.0)
    with pytest.raises(TrackingInputError):
        Coverage(0.0, 0.0, math.nan, 0.0, 5.0)


def test_a_track_that_leaves_coverage_ends_after_outside_time():
    """The target leaves the 300 m window after t = 10 (estimate outside from t = 11): it ends at 11 + 5."""
    cfg = config(**{'clutter.source': 'constant', 'clutter.density': 1e-7, 'track.outside_time': 5.0,
                    'detection.probability': 0.5})           # low P_D: existence alone decays slowly
    window = Coverage(0.0, 0.0, 0.0, 0.0, 300.0)
    with_cov, without = ImmIpdaTracker(cfg), ImmIpdaTracker(cfg)
    for k in range(17):
        pos = np.array([[200.0 + 10.0 * k, 0.0]])
        z = pos if pos[0, 0] <= 300.0 else np.zeros((0, 2))       # seen only inside the window
        out = with_cov.step(float(k), z, None, None, coverage=None if k in (3, 13) else window)
        ref = without.step(float(k), z)
        if k < 16:
            assert len(out) == 1 and with_cov.report.left_coverage == 0, k
    assert with_cov.report.left_coverage == 1 and len(out) == 0
    assert len(ref) == 1 and ref['confirmed'][0], 'without coverage the coasting track is kept'

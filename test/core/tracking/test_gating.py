"""Gates (eq. 25), gate probability (eq. 28), candidate pairs and innovation statistics (eq. 26)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from sonar_tracking.core.tracking import (TrackingInputError, candidate_pairs, gate_probability, gate_threshold,
                                          innovations)
from sonar_tracking.core.tracking import gating


@pytest.mark.parametrize('dim', [1, 2, 3, 4])
def test_gate_threshold_is_the_chi_square_quantile(dim):
    for p in (0.9, 0.99, 0.999):
        g = gate_threshold(p, dim)
        assert g == pytest.approx(stats.chi2.ppf(p, dim), rel=1e-10)
        assert gate_probability(g, dim) == pytest.approx(p, rel=1e-12)
    assert gate_threshold(0.99, 2) == pytest.approx(-2 * math.log(0.01))
    assert gate_threshold(1.0) == math.inf and gate_probability(math.inf) == 1.0
    with pytest.raises(TrackingInputError):
        gate_threshold(0.0)


def brute_pairs(lo, hi, z):
    return sorted((i, j) for i in range(len(lo)) for j in range(len(z))
                  if np.all(z[j] >= lo[i]) and np.all(z[j] <= hi[i]))


@pytest.mark.parametrize('strips', [False, True])
def test_candidate_pairs_are_exactly_the_boxes_contents(monkeypatch, strips):
    if strips:
        monkeypatch.setattr(gating, '_BRUTE_FORCE_PAIRS', 0)
    rng = np.random.default_rng(6)
    for trial in range(150):
        T, N = rng.integers(0, 30), rng.integers(0, 50)
        z = rng.uniform(-100, 100, (N, 2))
        if trial % 3 == 0 and N:
            z[: N // 2] = np.round(z[: N // 2] / 10) * 10       # ties, points on box edges
        c = rng.uniform(-120, 120, (T, 2))
        h = rng.exponential(20, (T, 2)) * (rng.random((T, 1)) < 0.9)
        lo, hi = c - h, c + h
        if trial % 3 == 0 and T:
            lo, hi = np.round(lo / 10) * 10, np.round(hi / 10) * 10
        track, meas = candidate_pairs(lo, hi, z)
        assert sorted(zip(track.tolist(), meas.tolist())) == brute_pairs(lo, hi, z)
        assert np.all(np.diff(track) >= 0), 'pairs must come sorted by track'
        counts = gating.candidate_counts(lo, hi, z)
        assert counts.shape == (T,) and np.all(counts >= np.bincount(track, minlength=T)), \
            'candidate_counts must bound the pairs of every track'
        assert counts.sum() <= T * N


def test_candidate_pairs_edge_cases_of_the_strip_search(monkeypatch):
    monkeypatch.setattr(gating, '_BRUTE_FORCE_PAIRS', 0)
    z = np.array([[0.0, 0.0], [0.3, 1.0], [1.0, 2.0], [1.0, 0.1]])
    # Boxes starting exactly on the largest x, ending on the smallest, a point box, boxes outside.
    lo = np.array([[1.0, 0.0], [-5.0, -5.0], [0.3, 1.0], [2.0, 0.0], [-1.0, 3.0]])
    hi = np.array([[3.0, 3.0], [0.0, 0.0], [0.3, 1.0], [3.0, 3.0], [5.0, 4.0]])
    track, meas = candidate_pairs(lo, hi, z)
    assert sorted(zip(track.tolist(), meas.tolist())) == brute_pairs(lo, hi, z) == [(0, 2), (0, 3), (1, 0), (2, 1)]


def test_candidate_pairs_without_gate_give_every_pair():
    z = np.zeros((3, 2))
    lo, hi = np.full((2, 2), -np.inf), np.full((2, 2), np.inf)
    track, meas = candidate_pairs(lo, hi, z)
    assert list(zip(track, meas)) == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)]


def random_spd(rng, shape, d):
    a = rng.normal(size=shape + (d, d))
    return a @ np.swapaxes(a, -1, -2) + 0.5 * np.eye(d)


@pytest.mark.parametrize('d', [1, 2, 3])
def test_innovations_match_direct_linear_algebra(d):
    rng = np.random.default_rng(7)
    M, Pn = 3, 11
    z = rng.normal(size=(d, Pn)) * 10
    R = np.moveaxis(random_spd(rng, (Pn,), d), 0, -1)                 # (d, d, P)
    zp = rng.normal(size=(d, M, Pn)) * 10
    hph = np.moveaxis(random_spd(rng, (M, Pn), d), (0, 1), (2, 3))   # (d, d, M, P)
    inn = innovations(z, R, zp, hph)
    for m in range(M):
        for p in range(Pn):
            S = hph[:, :, m, p] + R[:, :, p]
            nu = z[:, p] - zp[:, m, p]
            np.testing.assert_allclose(inn.nu[:, m, p], nu)
            np.testing.assert_allclose(inn.s_inv[:, :, m, p], np.linalg.inv(S), rtol=1e-10)
            assert inn.d2[m, p] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-10)
            assert inn.det[m, p] == pytest.approx(np.linalg.det(S), rel=1e-10)
            assert inn.density()[m, p] == pytest.approx(stats.multivariate_normal(zp[:, m, p], S).pdf(z[:, p]),
                                                        rel=1e-10)
    with pytest.raises(TrackingInputError):
        innovations(z[:, :3], R, zp, hph)

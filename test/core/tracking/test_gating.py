"""Gates (eq. 25), gate probability (eq. 28), candidate pairs and innovation statistics (eq. 26)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from sonar_tracking.core.tracking import (
    TrackingInputError,
    candidate_pairs,
    gate_probability,
    gate_threshold,
    gating,
    innovations,
)


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


@pytest.mark.parametrize('d', [1, 2, 3])
def test_gate_pairs_keeps_exactly_the_pairs_some_mode_validates(d):
    """The compiled d = 2 path and the general one: every candidate pair some mode's gate holds is
    kept, in order, with the statistics of :func:`innovations` on that pair."""
    rng = np.random.default_rng(11 + d)
    M, T, N = 3, 6, 9
    track_side = np.concatenate((rng.normal(size=(d, M, T)) * 3,
                                 np.moveaxis(random_spd(rng, (M, T), d), (0, 1), (2, 3)).reshape(d * d, M, T)))
    z = rng.normal(size=(d, N)) * 3
    R = np.moveaxis(random_spd(rng, (N,), d), 0, -1)
    meas_side = np.concatenate((z, R.reshape(d * d, N)))
    pt, pm = np.repeat(np.arange(T), N), np.tile(np.arange(N), T)
    gamma = gate_threshold(0.9, d)
    kt, km, inn, in_gate = gating.gate_pairs(track_side, meas_side, pt.copy(), pm.copy(), gamma)
    ref = innovations(z[:, pm], R[:, :, pm], track_side[:d][:, :, pt],
                      track_side[d:].reshape(d, d, M, T)[..., pt])
    valid = (ref.d2 < gamma).any(axis=0)
    assert 0 < valid.sum() < len(pt)                 # both outcomes occur
    np.testing.assert_array_equal(kt, pt[valid])
    np.testing.assert_array_equal(km, pm[valid])
    np.testing.assert_array_equal(in_gate, ref.d2[:, valid] < gamma)
    for name in ('nu', 's_inv', 'w', 'd2', 'det'):
        np.testing.assert_array_equal(getattr(inn, name), getattr(ref, name)[..., valid])


def test_gate_boxes_hold_every_mode_and_a_nan_gives_a_nan_box():
    """The boxes are the union over modes of ``centre +- sqrt(gamma (H P H^T_jj + max R_jj))``; a NaN
    centre or variance makes the whole box NaN (np.minimum / np.maximum semantics), which the box
    search treats as no gate."""
    rng = np.random.default_rng(3)
    c, h = rng.normal(size=(2, 3, 7)) * 50, rng.random((2, 3, 7)) * 20
    c[0, 1, 2], h[1, 2, 4] = np.nan, np.nan
    r = np.array([1.0, 4.0])
    lo, hi = gating.gate_boxes(c, h, r, 9.21)
    half = np.sqrt(9.21 * (h + r[:, None, None]))
    np.testing.assert_array_equal(lo, np.minimum.reduce(c - half, axis=1).T)
    np.testing.assert_array_equal(hi, np.maximum.reduce(c + half, axis=1).T)
    assert np.isnan(lo[2, 0]) and np.isnan(hi[4, 1]) and np.isfinite(lo[0]).all()
    assert gating.BoxSearch(lo, hi, rng.normal(size=(5, 2))).kind == 'all'

"""The Gaussian particle filter's maths (eqs. 5-12), the likelihood of eq. (13), the fusions of
eqs. (14)-(18) and the fuzzy weights of Tables 8-9, each against a direct computation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.gpf import fusion, fuzzy, sir
from sonar_tracking.core.gpf.cues import CUE_SPECS, CueModel, window_pixels
from sonar_tracking.core.gpf.ekf import polar_measurement
from sonar_tracking.core.gpf.gaussian import (
    condition_velocity,
    floor_position,
    kalman_update,
    motion_matrices,
    predict,
    propagate,
    sample_gaussian,
    weighted_moments,
)
from sonar_tracking.core.tracking import ConstantVelocity, white_noise_acceleration

P = np.array([[0.5, 0.1, 0.02, 0.0], [0.1, 0.4, 0.0, 0.01], [0.02, 0.0, 0.09, 0.0], [0.0, 0.01, 0.0, 0.06]])
X = np.array([15.0, -2.0, 0.25, 0.1])


def test_sampling_and_moments():
    rng = np.random.default_rng(1)
    s = sample_gaussian(X, P, 200_000, rng)
    m, c = weighted_moments(s)
    np.testing.assert_allclose(m, X, atol=0.01)
    np.testing.assert_allclose(c, P, atol=0.01)
    # Weighted moments (eq. 8) against numpy's weighted average and biased covariance.
    w = rng.random(50)
    w /= w.sum()
    pts = rng.normal(size=(50, 4))
    m, c = weighted_moments(pts, w)
    np.testing.assert_allclose(m, np.average(pts, axis=0, weights=w))
    np.testing.assert_allclose(c, np.cov(pts.T, aweights=w, bias=True), atol=1e-12)
    # A covariance that is not positive definite is still sampled (jittered), finite.
    bad = np.diag([1.0, 0.0, -1e-12, 0.0])
    assert np.isfinite(sample_gaussian(X, bad, 10, rng)).all()


def test_prediction_samples_the_shared_motion_model():
    """Eqs. (9)-(12) with the CV model and white-noise acceleration of core.tracking: the sample
    moments tend to F x and F P F^T + Q."""
    F, Q = motion_matrices(5.0, 0.004)
    np.testing.assert_array_equal(F, ConstantVelocity(2).transition(5.0))
    np.testing.assert_array_equal(Q, white_noise_acceleration(5.0, 0.004))
    m, c = predict(X, P, 5.0, 0.004, 400_000, np.random.default_rng(2))
    np.testing.assert_allclose(m, F @ X, atol=0.01)
    np.testing.assert_allclose(c, F @ P @ F.T + Q, atol=0.02)
    # Without noise the move is exactly F x for every particle.
    pts = sample_gaussian(X, P, 5, np.random.default_rng(3))
    np.testing.assert_allclose(propagate(pts, F, np.zeros((4, 4)), np.random.default_rng(4)), pts @ F.T)


def test_kalman_update_and_the_polar_jacobian():
    H = np.eye(2, 4)
    R = np.diag([0.09, 0.09])
    z = np.array([15.3, -1.8])
    m, c = kalman_update(X, P, z - H @ X, H, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    np.testing.assert_allclose(m, X + K @ (z - H @ X))
    np.testing.assert_allclose(c, (np.eye(4) - K @ H) @ P, atol=1e-12)
    sensor = (1.0, 2.0, 0.3)
    h, J = polar_measurement(X, sensor)
    assert h[0] == pytest.approx(math.hypot(X[0] - 1.0, X[1] - 2.0))
    assert h[1] == pytest.approx(math.atan2(X[1] - 2.0, X[0] - 1.0) - 0.3)
    eps = 1e-6
    num = np.column_stack([(polar_measurement(X + eps * e, sensor)[0] - polar_measurement(X - eps * e, sensor)[0])
                           / (2 * eps) for e in np.eye(4)])
    np.testing.assert_allclose(J, num, atol=1e-7)


def test_velocity_by_conditioning_is_the_exact_posterior():
    """With a Gaussian position measurement the exact posterior is the Kalman update; given that
    update's position moments, conditioning on the prior gives back its whole mean and covariance."""
    H, R = np.eye(2, 4), np.diag([0.05, 0.08])
    m, c = kalman_update(X, P, np.array([0.4, -0.3]), H, R)
    cm, cc = condition_velocity(X, P, m[:2], c[:2, :2])
    np.testing.assert_allclose(cm, m, atol=1e-12)
    np.testing.assert_allclose(cc, c, atol=1e-12)
    # The position moments are passed through; no position change leaves the velocity prior's mean.
    cm, cc = condition_velocity(X, P, X[:2], P[:2, :2])
    np.testing.assert_allclose(cm, X)
    np.testing.assert_allclose(cc, P, atol=1e-12)


def test_velocity_by_conditioning_has_less_monte_carlo_error():
    """A sharp likelihood of the position (as multiplicative fusion gives) leaves eq. 8 a few
    effective particles: their weighted velocity mean scatters from draw to draw and their velocity
    variance collapses; conditioning gives the exact velocity moments from the same draws."""
    H, R = np.eye(2, 4), np.diag([0.002, 0.002])
    z = X[:2] + np.array([0.3, -0.2])
    exact_m, exact_c = kalman_update(X, P, z - X[:2], H, R)
    rng = np.random.default_rng(11)
    plain_v, cond_v, plain_var, cond_var = [], [], [], []
    for _ in range(400):
        pts = sample_gaussian(X, P, 300, rng)
        logw = -0.5 * np.sum((pts[:, :2] - z) ** 2 / np.diag(R), axis=1)
        w = np.exp(logw - logw.max())
        w /= w.sum()
        m, c = weighted_moments(pts, w)
        cm, cc = condition_velocity(X, P, m[:2], c[:2, :2])
        plain_v.append(m[2:]), cond_v.append(cm[2:])
        plain_var.append(np.diag(c)[2:]), cond_var.append(np.diag(cc)[2:])
    plain_err = np.mean(np.sum((np.array(plain_v) - exact_m[2:]) ** 2, axis=1))
    cond_err = np.mean(np.sum((np.array(cond_v) - exact_m[2:]) ** 2, axis=1))
    assert cond_err < 0.5 * plain_err
    exact_var = np.diag(exact_c)[2:]
    assert np.all(np.median(plain_var, axis=0) < 0.8 * exact_var)          # eq. 8 alone: overconfident
    np.testing.assert_allclose(np.median(cond_var, axis=0), exact_var, rtol=0.1)


def test_position_floor():
    c = np.diag([1e-6, 0.5, 0.1, 0.1])
    f = floor_position(c, 0.01)
    assert np.linalg.eigvalsh(f[:2, :2]).min() == pytest.approx(0.01)
    assert f[1, 1] == pytest.approx(0.5) and f[2, 2] == 0.1
    assert floor_position(P, 0.01) is P


def test_sir_roughening_floors_the_particle_spread():
    rng = np.random.default_rng(4)
    # A resampled cloud: 300 copies of three particles, 5 cm apart along x.
    base = np.array([[10.0, 2.0, 0.3, 0.0], [10.05, 2.0, 0.3, 0.0], [10.1, 2.0, 0.31, 0.0]])
    cloud = base[rng.integers(0, 3, 300)]
    out = sir.roughen(cloud, 0.5 ** 2, rng)
    m0, c0 = weighted_moments(cloud)
    m1, c1 = weighted_moments(out)
    assert np.linalg.eigvalsh(c1[:2, :2]).min() == pytest.approx(0.25, rel=0.2)   # 300 draws: ~8 % std
    np.testing.assert_allclose(m1[:2], m0[:2], atol=0.1)
    np.testing.assert_array_equal(out[:, 2:], cloud[:, 2:])                      # velocities untouched
    wide = sample_gaussian(X, P, 300, rng)
    assert sir.roughen(wide, 0.2 ** 2, rng) is wide                              # already wider: unchanged


def test_likelihood_of_eq_13():
    cm = CueModel((3, 24), 0.7, alpha=0.8)
    values = np.array([[3.0, 5.0, 1.0], [0.8, 0.9, 1.0]])
    template = np.array([3.0, 0.85])
    d2 = cm.distances2(values, template)
    sig = np.array([CUE_SPECS[3].sigma, CUE_SPECS[24].sigma])
    np.testing.assert_allclose(d2, ((values - template[:, None]) / sig[:, None]) ** 2)
    lp = cm.log_likelihoods(d2)
    direct = np.log(1.0 / math.sqrt(2 * math.pi * 0.8) * np.exp(-d2 / (2 * 0.8 ** 2)))
    np.testing.assert_allclose(lp, direct)
    assert cm.match(d2).shape == (3,)


def test_cue_model_checks_and_window_size():
    with pytest.raises(ValueError, match='same for every window'):
        CueModel((3, 1), 0.7)
    assert [window_pixels(w, 0.1) for w in (0.05, 0.3, 0.7, 0.8, 1.1, 50.0)] == [3, 3, 7, 9, 11, 41]
    assert window_pixels(0.7, 0.05) == 15
    assert all(s.sigma > 0 and s.threshold > 0 for s in CUE_SPECS.values())


def test_normalised_weights_are_finite_whatever_the_log_likelihoods():
    cases = [np.array([0.0, -1e308, -np.inf, np.nan]), np.full(5, -np.inf), np.array([1e308, 1e308, -1e308]),
             np.array([np.nan, np.nan]), np.random.default_rng(5).normal(0, 1e4, 300)]
    for lw in cases:
        w = fusion.normalise_log(lw)
        assert np.isfinite(w).all() and (w >= 0).all() and w.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(fusion.normalise_log(np.full(4, -np.inf)), 0.25)


def test_multiplicative_and_weighted_fusion():
    rng = np.random.default_rng(6)
    p = rng.random((3, 20)) + 0.01
    a = np.array([0.5, 0.3, 0.2])
    np.testing.assert_allclose(np.exp(fusion.multiplicative(np.log(p))), p.prod(axis=0))
    np.testing.assert_allclose(np.exp(fusion.weighted(np.log(p), a)), (a[:, None] * p).sum(axis=0))
    # Far in the tails the log domain still answers (the plain sum would be 0).
    tiny = np.log(p) - 2000.0
    assert np.isfinite(fusion.weighted(tiny, a)).all()


def test_cue_spread_of_eqs_16_17():
    rng = np.random.default_rng(7)
    pos = rng.normal(size=(40, 2))
    w = rng.random((3, 40))
    w /= w.sum(axis=1, keepdims=True)
    got = fusion.cue_spreads(pos, w)
    for i in range(3):
        mean = sum(w[i, n] * pos[n] for n in range(40))
        A = sum(w[i, n] * np.outer(pos[n] - mean, pos[n] - mean) for n in range(40))
        assert got[i] == pytest.approx(math.sqrt(np.sum(A * A)))


def test_adaptive_switch_of_eq_18():
    rng = np.random.default_rng(8)
    pos = rng.normal(0.0, 1.0, (300, 2))
    peaked = -0.5 * np.sum(pos ** 2, axis=1) / 0.05           # concentrates the particles
    flat = np.zeros(300)                                          # says nothing
    th = np.array([2.0, 2.0])
    good = fusion.fuse(np.stack([peaked, peaked]), pos, th, 'af')
    assert good.mode == fusion.MF and good.a is None and np.all(good.inverse_spread > 2.0)
    mixed = fusion.fuse(np.stack([peaked, flat]), pos, th, 'af')
    assert mixed.mode == fusion.WF and mixed.a[0] > 0.9 and mixed.a.sum() == pytest.approx(1.0)
    assert mixed.inverse_spread[1] == pytest.approx(1.0)           # Delta_0 / Delta_i of a flat cue
    assert fusion.fuse(np.stack([peaked, flat]), pos, th, 'mf').mode == fusion.MF
    assert fusion.fuse(np.stack([peaked, peaked]), pos, th, 'wf').mode == fusion.WF
    with pytest.raises(ValueError, match='af, mf or wf'):
        fusion.fuse(np.stack([peaked]), pos, th[:1], 'sum')


def test_crossing_switch_gives_wf_when_a_second_target_is_in_the_cloud():
    # Two targets in the cloud, every cue sharp on both: eq. 18 alone says MF (each cue concentrates
    # the particles), the crossing switch says WF while the other track's prediction is inside.
    rng = np.random.default_rng(9)
    mean, cov = np.array([0.0, 0.0]), np.diag([1.0, 1.0])
    pos = rng.multivariate_normal(mean, cov, 300)
    blobs = [np.array([-0.6, 0.0]), np.array([0.6, 0.0])]
    peak = np.logaddexp(*[-0.5 * np.sum((pos - b) ** 2, axis=1) / 0.02 for b in blobs])
    th = np.array([2.0, 2.0])
    log_p = np.stack([peak, peak])
    assert fusion.fuse(log_p, pos, th, 'af').mode == fusion.MF
    inside = np.array([[0.6, 0.0]])
    outside = np.array([[4.0, 0.0]])                                   # d^2 16 > 9.21
    assert fusion.second_target(mean, cov, inside, 9.21)
    assert not fusion.second_target(mean, cov, outside, 9.21)
    assert not fusion.second_target(mean, cov, None, 9.21)
    assert not fusion.second_target(mean, cov, np.zeros((0, 2)), 9.21)
    assert fusion.second_target(mean, np.diag([9.0, 1.0]), outside, 9.21)   # a wide cloud reaches it
    crowded = fusion.fuse(log_p, pos, th, 'af', crowded=True)
    assert crowded.mode == fusion.WF and crowded.a.sum() == pytest.approx(1.0)
    assert fusion.fuse(log_p, pos, th, 'mf', crowded=True).mode == fusion.MF    # fixed modes ignore it


def test_fuzzy_memberships_rules_and_weights():
    u = np.linspace(-1, 1, 41)
    mu = fuzzy.memberships(u)
    np.testing.assert_allclose(mu.sum(axis=1), 1.0)               # partition of unity
    assert (np.count_nonzero(mu, axis=1) <= 2).all()
    np.testing.assert_array_equal(fuzzy.memberships(np.array([-1.0, 0.0, 1.0])), np.eye(5)[[0, 2, 4]])
    # Table 9 at the set peaks: rows f_else NB..PB, columns own NB..PB.
    ratios = 2.0 ** (2 * fuzzy._PEAKS)                              # universe -1, -0.5, 0, 0.5, 1
    for r, row in enumerate(fuzzy.RULES):
        for c, level in enumerate(row):
            assert fuzzy.fuzzy_levels(np.array(ratios[c]), np.array(ratios[r])) == pytest.approx(level)
    # Between the peaks the level is interpolated; beyond the universe it saturates.
    mid = fuzzy.fuzzy_levels(np.array(2 ** 0.5), np.array(1.0))   # own halfway ZE -> PS, others ZE
    assert mid == pytest.approx(3.5)
    assert fuzzy.fuzzy_levels(np.array(1e6), np.array(1e-6)) == 5.0
    # Weights: positive, summing to one; a cue better than the others weighs more.
    a = fuzzy.fuzzy_weights(np.array([8.0, 1.0, 1.0, 0.25]), np.ones(4))
    assert a.sum() == pytest.approx(1.0) and (a > 0).all() and a[0] > a[1] > a[3]
    assert a[1] == pytest.approx(a[2])
    assert fuzzy.fuzzy_weights(np.array([3.0]), np.array([2.0])) == pytest.approx([1.0])
    equal = fuzzy.fuzzy_weights(np.full(5, 1.7), np.full(5, 1.0))
    np.testing.assert_allclose(equal, 0.2)

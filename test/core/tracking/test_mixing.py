"""Moment matching and IMM interaction / combination (eqs. 17-20, 41-42), against plain loops."""
from __future__ import annotations

import numpy as np
import pytest

from sonar_tracking.core.tracking import combine, interaction, mode_transition_matrix, moment_match


def random_modes(rng, t, m, n=4, offset=0.0):
    x = rng.normal(size=(n, m, t)) * 3 + offset
    a = rng.normal(size=(n, n, m, t))
    P = np.einsum('ikmt,jkmt->ijmt', a, a) + np.eye(n)[:, :, None, None]
    mu = rng.dirichlet(np.ones(m), size=t).T
    return mu, x, P


def loop_moment_match(w, x, P):
    """sum_k w_k (P_k + (x_k - x)(x_k - x)^T) per item, by loops."""
    n, k, t = x.shape
    mean = np.zeros((n, t))
    cov = np.zeros((n, n, t))
    for i in range(t):
        mean[:, i] = sum(w[j, i] * x[:, j, i] for j in range(k))
        for j in range(k):
            d = x[:, j, i] - mean[:, i]
            cov[:, :, i] += w[j, i] * (P[:, :, j, i] + np.outer(d, d))
    return mean, cov


def test_moment_match_equals_the_mixture_formula():
    rng = np.random.default_rng(1)
    mu, x, P = random_modes(rng, 7, 3)
    mean, cov = moment_match(mu, x, P)
    ref_mean, ref_cov = loop_moment_match(mu, x, P)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-12)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-10, atol=1e-12)


def test_moment_match_is_translation_invariant_at_harbour_distances():
    """Unlike eq. (42) as printed (which subtracts x x^T), the covariance ignores where the origin is."""
    rng = np.random.default_rng(2)
    mu, x, P = random_modes(rng, 5, 3)
    _, cov = moment_match(mu, x, P)
    _, cov_far = moment_match(mu, x + 3.0e3, P)
    np.testing.assert_allclose(cov_far, cov, rtol=1e-9, atol=1e-9)
    mean, _ = moment_match(mu, x, P)
    printed_42 = cov - mean[:, None] * mean[None, :]
    assert not np.allclose(printed_42, cov)


def test_interaction_eqs_17_to_20():
    rng = np.random.default_rng(3)
    pi = mode_transition_matrix(3, 0.98)
    mu, x, P = random_modes(rng, 6, 3)
    mu_pred, x0, P0 = interaction(mu, x, P, pi)
    for t in range(6):
        for m in range(3):
            c = sum(pi[n, m] * mu[n, t] for n in range(3))                      # eq. (20)
            assert mu_pred[m, t] == pytest.approx(c, rel=1e-14)
            w = np.array([pi[n, m] * mu[n, t] / c for n in range(3)])        # eq. (19)
            xm = sum(w[n] * x[:, n, t] for n in range(3))                     # eq. (17)
            Pm = sum(w[n] * (P[:, :, n, t] + np.outer(x[:, n, t] - xm, x[:, n, t] - xm)) for n in range(3))
            np.testing.assert_allclose(x0[:, m, t], xm, rtol=1e-12)
            np.testing.assert_allclose(P0[:, :, m, t], Pm, rtol=1e-10, atol=1e-12)


def test_interaction_of_identical_modes_changes_nothing():
    rng = np.random.default_rng(4)
    mu, x, P = random_modes(rng, 4, 1)
    x3, P3 = np.repeat(x, 3, axis=1), np.repeat(P, 3, axis=2)
    mu3 = rng.dirichlet(np.ones(3), size=4).T
    _, x0, P0 = interaction(mu3, x3, P3, mode_transition_matrix(3, 0.9))
    np.testing.assert_allclose(x0, x3, rtol=1e-14)
    np.testing.assert_allclose(P0, P3, rtol=1e-13)


def test_combination_eqs_41_42_and_a_zero_probability_mode():
    rng = np.random.default_rng(5)
    mu, x, P = random_modes(rng, 5, 3)
    xc, Pc = combine(mu, x, P)
    ref_x, ref_P = loop_moment_match(mu, x, P)
    np.testing.assert_allclose(xc, ref_x, rtol=1e-12)
    np.testing.assert_allclose(Pc, ref_P, rtol=1e-10, atol=1e-12)
    # A mode with zero predicted probability keeps its own estimate in the interaction.
    pi = np.eye(3)
    mu0 = np.array([[1.0], [0.0], [0.0]])
    _, x0, P0 = interaction(mu0, x[..., :1], P[..., :1], pi)
    assert np.isfinite(x0).all() and np.isfinite(P0).all()
    np.testing.assert_allclose(x0, x[..., :1])

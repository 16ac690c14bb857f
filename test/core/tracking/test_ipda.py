"""The vectorised IMM-IPDA update against the paper's equations (28)-(40) written out literally."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from sonar_tracking.core.tracking import innovations, ipda_update, update_existence
from sonar_tracking.core.tracking.ipda import segment_sum


def paper_update(xp, Pp, mup, ep, z, R, rho, gates, pd, pg):
    """One track, eqs. (28)-(40) with loops; eq. (36) in its standard form (no trailing - x x^T).

    ``xp (M, n)``, ``Pp (M, n, n)``, ``z (n_meas, 2)``, ``R (n_meas, 2, 2)``, ``gates (M, n_meas)`` bool.
    """
    M, n = xp.shape
    n_meas = len(z)
    H = np.eye(2, n)
    pm = np.zeros((M, n_meas))
    for m in range(M):
        for i in range(n_meas):
            S = H @ Pp[m] @ H.T + R[i]                                             # eq. (26)
            if gates[m, i]:
                pm[m, i] = stats.multivariate_normal(H @ xp[m], S).pdf(z[i]) / pg  # eq. (28)
    p = mup @ pm                                                                   # eq. (29)
    lam = 1 - pd * pg + pd * pg * np.sum(p / rho)                                  # eq. (33)
    beta = np.concatenate(([(1 - pd * pg) / lam], pd * pg * p / (lam * rho)))     # eq. (32)
    mu_i = np.zeros((M, n_meas + 1))
    mu_i[:, 0] = mup
    for i in range(n_meas):
        mu_i[:, i + 1] = mup * pm[:, i] / p[i]                                     # eq. (31)
    mu = mu_i @ beta                                                               # eq. (30)
    x_out, P_out = np.zeros((M, n)), np.zeros((M, n, n))
    for m in range(M):
        bm = beta * mu_i[m] / mu[m]                                                # eq. (34)
        xs, Ps = [xp[m]], [Pp[m]]
        for i in range(n_meas):
            S = H @ Pp[m] @ H.T + R[i]
            K = Pp[m] @ H.T @ np.linalg.inv(S)                                     # eq. (39)
            xs.append(xp[m] + K @ (z[i] - H @ xp[m]))                              # eq. (37)
            Ps.append((np.eye(n) - K @ H) @ Pp[m])                                 # eq. (38)
        x_out[m] = sum(b * x for b, x in zip(bm, xs))                              # eq. (35)
        P_out[m] = sum(b * (P + np.outer(x - x_out[m], x - x_out[m])) for b, x, P in zip(bm, xs, Ps))  # eq. (36)
    e = ep * lam / (1 - (1 - lam) * ep)                                            # eq. (40)
    return x_out, P_out, mu, e, lam


def test_vectorised_update_equals_the_paper_equations():
    rng = np.random.default_rng(11)
    T, M, n, N = 5, 3, 4, 9
    xp = rng.normal(size=(n, M, T)) * [[[30.0]], [[30.0]], [[3.0]], [[3.0]]]
    a = rng.normal(size=(n, n, M, T))
    Pp = np.einsum('ikmt,jkmt->ijmt', a, a) * 4 + np.eye(n)[:, :, None, None] * 5
    mup = rng.dirichlet(np.ones(M), size=T).T
    ep = rng.uniform(0.05, 0.95, T)
    z = rng.normal(size=(N, 2)) * 30
    b = rng.normal(size=(N, 2, 2))
    R = b @ b.transpose(0, 2, 1) + np.eye(2)
    rho = rng.uniform(1e-5, 1e-3, N)
    # Pairs sorted by track; track 3 has none; some pairs are in only some modes' gates.
    pairs = [(0, 0), (0, 3), (0, 4), (1, 1), (2, 2), (2, 5), (2, 6), (2, 7), (4, 8), (4, 0)]
    pt = np.array([p[0] for p in pairs])
    pm = np.array([p[1] for p in pairs])
    gates = rng.random((M, len(pairs))) < 0.7
    gates[:, 0] = True
    gates[rng.integers(0, M, len(pairs)), np.arange(len(pairs))] = True   # validated: in some mode's gate
    gates[0, 1], gates[1:, 1] = False, True
    inn = innovations(z[pm].T, R[pm].transpose(1, 2, 0), xp[:2][..., pt], Pp[:2, :2][..., pt])
    for pd, pg in ((0.9, 0.99), (0.57, 0.95), (1.0, 0.999)):
        res = ipda_update(xp, Pp, mup, ep, pt, inn, gates, rho[pm], pd, pg)
        for t in range(T):
            sel = np.flatnonzero(pt == t)
            xr, Pr, mur, er, lamr = paper_update(xp[..., t].T, np.moveaxis(Pp[..., t], -1, 0), mup[:, t], ep[t],
                                                  z[pm[sel]], R[pm[sel]], rho[pm[sel]], gates[:, sel], pd, pg)
            np.testing.assert_allclose(res.lam[t], lamr, rtol=1e-10)
            np.testing.assert_allclose(res.existence[t], er, rtol=1e-10)
            np.testing.assert_allclose(res.mu[:, t], mur, rtol=1e-10)
            np.testing.assert_allclose(res.x[..., t].T, xr, rtol=1e-10, atol=1e-10)
            np.testing.assert_allclose(np.moveaxis(res.P[..., t], -1, 0), Pr, rtol=1e-9, atol=1e-9)


def test_track_without_measurements_is_a_missed_detection():
    xp = np.zeros((4, 1, 1))
    Pp = np.eye(4)[:, :, None, None] * 7.0
    res = ipda_update(xp, Pp, np.ones((1, 1)), np.array([0.4]), np.zeros(0, np.intp),
                      innovations(np.zeros((2, 0)), np.zeros((2, 2, 0)), np.zeros((2, 1, 0)), np.zeros((2, 2, 1, 0))),
                      np.zeros((1, 0), bool), np.zeros(0), 0.9, 0.99)
    lam = 1 - 0.9 * 0.99
    assert res.lam[0] == pytest.approx(lam)
    assert res.existence[0] == pytest.approx(update_existence(np.array([0.4]), np.array([lam]))[0])
    np.testing.assert_array_equal(res.x, xp)
    np.testing.assert_allclose(res.P, Pp)


@pytest.mark.parametrize('n_pairs', [5, 5000])
def test_segment_sum_both_paths_add_in_order(n_pairs):
    rng = np.random.default_rng(12)
    seg = np.sort(rng.integers(0, 40, n_pairs))
    vals = rng.normal(size=(3, n_pairs)) * 10.0 ** rng.integers(-8, 8, n_pairs)
    got = segment_sum(vals, seg, 45)
    ref = np.zeros((3, 45))
    for k in range(n_pairs):
        ref[:, seg[k]] += vals[:, k]
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=0)

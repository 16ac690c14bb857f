"""Moment matching of Gaussian mixtures: the one formula behind eqs. (18), (36) and (42).

A mixture ``sum_k w_k N(x_k, P_k)`` (weights summing to one) has mean ``x = sum_k w_k x_k`` and
covariance ``P = sum_k w_k (P_k + (x_k - x)(x_k - x)^T)``. That is the standard IMM mixing
covariance (Blom & Bar-Shalom 1988), the PDA posterior covariance and the IMM output
covariance. As printed, the paper's eq. (18) puts the mixing weight outside the sum over n
(with the weight inside, ``sum_n mu (P_n + x_n x_n^T) - x x^T`` would be the second-moment form
of the formula above), and eqs. (36) and (42) subtract an extra ``x x^T`` after the spread
about the mean, which makes them depend on the origin of the coordinates. None of the three
is the covariance of its mixture, so all three are computed by :func:`moment_match` (eq. 36
in the algebraically equal form of :mod:`~sonar_tracking.core.tracking.ipda`).
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.jit import kernel

__all__ = ['moment_match', 'moment_match_into']


def moment_match(weights: np.ndarray, means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Means and covariances of J mixtures of the same K components, for T items at once.

    Arrays are component-major with the items last (see :mod:`~sonar_tracking.core.tracking`).

    Parameters
    ----------
    weights : ``(J, K, T)`` weights of mixture j over the K components (summing to one over K);
        ``(K, T)`` for one mixture per item.
    means : ``(n, K, T)`` component means.
    covs : ``(n, n, K, T)`` component covariances.

    Returns
    -------
    means ``(n, J, T)`` and covariances ``(n, n, J, T)`` (``(n, T)`` and ``(n, n, T)`` for
    ``(K, T)`` weights). Second moments are taken about the first component's mean, not the
    origin, so coordinates far from the origin (kilometres) cost no precision; what cancels is
    the spread between components against their covariances.
    """
    w = np.asarray(weights, dtype=float)
    single = w.ndim == 2
    if single:
        w = w[None]
    n, k, t = means.shape
    mean, cov = np.empty((n, w.shape[0], t)), np.empty((n, n, w.shape[0], t))
    moment_match_into(w, means, covs, mean, cov)
    if single:
        return mean[:, 0], cov[:, :, 0]
    return mean, cov


@kernel
def moment_match_into(w, means, covs, mean_out, cov_out):
    """:func:`moment_match` of ``w (J, K, T)`` into ``mean_out (n, J, T)``, ``cov_out (n, n, J, T)``
    (compiled, items innermost; callable from other kernels). Sums run over the components in order."""
    n_mix, n_comp, n_items = w.shape
    n = means.shape[0]
    y = np.empty((n, n_comp, n_items))
    for a in range(n):
        for k in range(n_comp):
            for t in range(n_items):
                y[a, k, t] = means[a, k, t] - means[a, 0, t]
    y_bar = np.empty((n, n_items))
    for j in range(n_mix):
        for a in range(n):
            for t in range(n_items):
                y_bar[a, t] = 0.0
            for k in range(n_comp):
                for t in range(n_items):
                    y_bar[a, t] += w[j, k, t] * y[a, k, t]
        for a in range(n):
            for b in range(n):
                for t in range(n_items):
                    cov_out[a, b, j, t] = 0.0
                for k in range(n_comp):
                    for t in range(n_items):
                        cov_out[a, b, j, t] += w[j, k, t] * (covs[a, b, k, t] + y[a, k, t] * y[b, k, t])
                for t in range(n_items):
                    cov_out[a, b, j, t] -= y_bar[a, t] * y_bar[b, t]
            for t in range(n_items):
                mean_out[a, j, t] = means[a, 0, t] + y_bar[a, t]

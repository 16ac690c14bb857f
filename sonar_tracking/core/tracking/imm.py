"""IMM interaction (eqs. 17-20) and combination (eqs. 41-42), for many tracks at once.

Arrays are component-major with tracks last: ``mu (M, T)``, ``x (n, M, T)``, ``P (n, n, M, T)``
for T tracks and M modes. The mode transition matrix follows
:mod:`~sonar_tracking.core.tracking.markov`: ``Pi[n, m] = P(mode m at k | mode n at k-1)``.

Eqs. (18) and (42) as printed are not the covariances of the mixtures they describe; both are
computed by :func:`~sonar_tracking.core.tracking.gaussian.moment_match` (standard IMM mixing and
output covariances, Blom & Bar-Shalom 1988), see that module.
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.jit import kernel
from sonar_tracking.core.tracking.gaussian import moment_match, moment_match_into

__all__ = ['interaction', 'combine']


def interaction(mu: np.ndarray, x: np.ndarray, P: np.ndarray, pi: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted mode probabilities and mixed initial conditions of every mode filter.

    Parameters
    ----------
    mu : ``(M, T)`` mode probabilities ``mu_{k-1|k-1}``.
    x, P : ``(n, M, T)``, ``(n, n, M, T)`` mode-conditioned estimates at k-1.
    pi : ``(M, M)`` transition matrix (eq. 21).

    Returns
    -------
    mu_pred ``(M, T)`` (eq. 20), mixed means ``(n, M, T)`` (eq. 17) and covariances
    ``(n, n, M, T)`` (eq. 18, standard form). A mode whose predicted probability is zero keeps
    its own estimate.
    """
    m, t = mu.shape
    mu_pred, omega = np.empty((m, t)), np.empty((m, m, t))
    x0, P0 = np.empty(x.shape), np.empty(P.shape)
    _interaction(mu, x, P, pi, mu_pred, omega, x0, P0)
    return mu_pred, x0, P0


@kernel
def _interaction(mu, x, P, pi, mu_pred, omega, x0, P0):
    """:func:`interaction` into the given arrays (compiled)."""
    n_modes, n_tracks = mu.shape
    for t in range(n_tracks):
        for m in range(n_modes):
            s = 0.0
            for k in range(n_modes):
                s += pi[k, m] * mu[k, t]                          # eq. (20)
            mu_pred[m, t] = s
            for k in range(n_modes):                              # eq. (19): (to m, from k)
                if s > 0.0:
                    omega[m, k, t] = pi[k, m] * mu[k, t] / s
                else:
                    omega[m, k, t] = 1.0 if k == m else 0.0
    moment_match_into(omega, x, P, x0, P0)                        # eqs. (17)-(18)


def combine(mu: np.ndarray, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Track output: the mode-probability weighted mixture, eqs. (41)-(42) (standard form).

    ``mu (M, T)``, ``x (n, M, T)``, ``P (n, n, M, T)`` -> ``x (n, T)``, ``P (n, n, T)``.
    """
    return moment_match(mu, x, P)

"""Markov chains of the IMM-IPDA: mode transitions (eq. 21) and target existence (eqs. 24, 40).

Convention: ``Pi[n, m] = P(mode m at k | mode n at k-1)``, rows sum to one. The paper's
``pi_(m,n)`` (eqs. 19-21) is the same probability written with the indices swapped; its
eq. (21) matrix is symmetric, so the numbers are the same either way.
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.jit import kernel
from sonar_tracking.core.tracking.errors import TrackingInputError

__all__ = ['mode_transition_matrix', 'predict_existence', 'update_existence', 'existence_posterior']


def mode_transition_matrix(n_modes: int, p_stay: float) -> np.ndarray:
    """Eq. (21): ``p_stay`` on the diagonal, the rest shared equally among the other modes.

    ``mode_transition_matrix(3, 0.98)`` is the paper's matrix. With one mode it is ``[[1]]``.
    """
    if n_modes < 1:
        raise TrackingInputError(f'need at least one mode, got {n_modes}')
    if not 0.0 < p_stay <= 1.0:
        raise TrackingInputError(f'p_stay = {p_stay} must be in (0, 1]')
    if n_modes == 1:
        return np.ones((1, 1))
    pi = np.full((n_modes, n_modes), (1.0 - p_stay) / (n_modes - 1))
    np.fill_diagonal(pi, p_stay)
    return pi


def predict_existence(p: np.ndarray, survival: float, birth: float = 0.0) -> np.ndarray:
    """Eq. (24), Markov chain one: ``P(chi_k | Z^{k-1})``.

    ``survival = P(chi_k | chi_{k-1})``, ``birth = P(chi_k | not chi_{k-1})``.
    """
    if birth == 0.0:
        # The birth term is exactly +0 for p in [0, 1] (and NaN stays NaN): skip it.
        return survival * p
    return survival * p + birth * (1.0 - p)


def update_existence(p_pred: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Eq. (40): ``P(chi_k | Z^k) = p Lambda / (1 - (1 - Lambda) p)``, with ``p`` from eq. (24).

    ``lam`` is the measurement likelihood ratio of eq. (33). The result is clipped to [0, 1];
    the 0/0 case (``p = 1`` and ``Lambda = 0``: a target certain to exist yet impossible to have
    missed) gives 0.
    """
    p_pred, lam = np.broadcast_arrays(np.asarray(p_pred, dtype=float), np.asarray(lam, dtype=float))
    out = np.empty(p_pred.shape)
    _existence_posteriors(p_pred.ravel(), lam.ravel(), out.reshape(-1))
    return out


@kernel
def existence_posterior(p, lam):
    """Eq. (40) for one track (compiled scalar; see :func:`update_existence`)."""
    num = p * lam
    den = (1.0 - p) + num
    out = num / den if den > 0.0 else 0.0
    return 1.0 if out > 1.0 else out


@kernel
def _existence_posteriors(p, lam, out):
    for i in range(len(p)):
        out[i] = existence_posterior(p[i], lam[i])

"""Kalman prediction for every track and mode, eqs. (22)-(23).

Arrays are component-major with tracks last: ``x (n, M, T)``, ``P (n, n, M, T)``. All tracks
are predicted to the same scan time, so each mode's ``F`` and ``Q`` are shared by every track.
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.jit import kernel

__all__ = ['predict']


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predict means ``(n, M, T)`` and covariances ``(n, n, M, T)`` with per-mode ``F``, ``Q`` ``(M, n, n)``.

    ``x_pred = F x`` (eq. 22), ``P_pred = F P F^T + Q`` (eq. 23), for every track.
    """
    x_pred, P_pred = np.empty(x.shape), np.empty(P.shape)
    _predict(x, P, F, Q, x_pred, P_pred)
    return x_pred, P_pred


@kernel
def _predict(x, P, F, Q, x_pred, P_pred):
    """:func:`predict` into ``x_pred``, ``P_pred`` (compiled; tracks innermost, so the loops vectorise)."""
    n, n_modes, n_tracks = x.shape
    fp = np.empty((n, n, n_tracks))
    for m in range(n_modes):
        for i in range(n):
            for t in range(n_tracks):
                x_pred[i, m, t] = 0.0
            for k in range(n):
                f = F[m, i, k]
                for t in range(n_tracks):
                    x_pred[i, m, t] += f * x[k, m, t]
            for j in range(n):
                for t in range(n_tracks):
                    fp[i, j, t] = 0.0
                for k in range(n):
                    f = F[m, i, k]
                    for t in range(n_tracks):
                        fp[i, j, t] += f * P[k, j, m, t]
        for i in range(n):
            for j in range(n):
                for t in range(n_tracks):
                    P_pred[i, j, m, t] = 0.0
                for k in range(n):
                    f = F[m, j, k]
                    for t in range(n_tracks):
                        P_pred[i, j, m, t] += fp[i, k, t] * f
                q = Q[m, i, j]
                for t in range(n_tracks):
                    P_pred[i, j, m, t] += q

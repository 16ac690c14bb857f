"""Kalman prediction for every track and mode, eqs. (22)-(23).

Arrays are component-major with tracks last: ``x (n, M, T)``, ``P (n, n, M, T)``. All tracks
are predicted to the same scan time, so each mode's ``F`` and ``Q`` are shared by every track.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel

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
    """:func:`predict` into ``x_pred``, ``P_pred`` (compiled)."""
    n, n_modes, n_tracks = x.shape
    fp = np.empty((n, n))
    for t in range(n_tracks):
        for m in range(n_modes):
            for i in range(n):
                s = 0.0
                for j in range(n):
                    s += F[m, i, j] * x[j, m, t]
                x_pred[i, m, t] = s
                for j in range(n):
                    s = 0.0
                    for k in range(n):
                        s += F[m, i, k] * P[k, j, m, t]
                    fp[i, j] = s
            for i in range(n):
                for j in range(n):
                    s = 0.0
                    for k in range(n):
                        s += fp[i, k] * F[m, j, k]
                    P_pred[i, j, m, t] = s + Q[m, i, j]

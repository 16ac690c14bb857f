"""Kalman prediction for every track and mode, eqs. (22)-(23).

Arrays are component-major with tracks last: ``x (n, M, T)``, ``P (n, n, M, T)``. All tracks
are predicted to the same scan time, so each mode's ``F`` and ``Q`` are shared by every track:
``F P F^T`` is one matrix product per mode over all tracks at once,
``vec(F P F^T) = (F kron F) vec(P)``, instead of one small product per track.
"""
from __future__ import annotations

import numpy as np

__all__ = ['predict', 'transition_operators', 'columns_matmul']

# Column blocks small enough that BLAS runs each product on one thread: on a busy machine a
# threaded product of this size waits for cores far longer than it computes.
_BLOCK_ELEMENTS = 1 << 17


def columns_matmul(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``a @ b`` for ``a (k, k)``, ``b (k, N)``, in column blocks (same result, single-threaded BLAS)."""
    cols = max(1, _BLOCK_ELEMENTS // max(1, a.size))
    if out is None:
        out = np.empty((a.shape[0], b.shape[1]))
    if b.shape[1] <= cols:
        np.matmul(a, b, out=out)
        return out
    for i in range(0, b.shape[1], cols):
        np.matmul(a, b[:, i:i + cols], out=out[:, i:i + cols])
    return out


def transition_operators(F: np.ndarray) -> np.ndarray:
    """``F_m kron F_m`` for each mode's ``F (M, n, n)``: the operators :func:`predict` applies to ``vec(P)``."""
    return np.stack([np.kron(f, f) for f in F])


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray,
            ops: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Predict means ``(n, M, T)`` and covariances ``(n, n, M, T)`` with per-mode ``F``, ``Q`` ``(M, n, n)``.

    ``x_pred = F x`` (eq. 22), ``P_pred = F P F^T + Q`` (eq. 23), for every track. ``ops`` may
    pass :func:`transition_operators` of ``F`` computed once for many calls.
    """
    n, m, t = x.shape
    if ops is None:
        ops = transition_operators(F)
    x_pred = np.einsum('mij,jmt->imt', F, x)
    p_flat = P.reshape(n * n, m, t)
    if t * ops.shape[1] * ops.shape[2] <= _BLOCK_ELEMENTS:
        # All modes in one batched product, (M, n^2, n^2) @ (M, n^2, T), small enough for one thread.
        out = np.matmul(ops, p_flat.transpose(1, 0, 2)).transpose(1, 0, 2)
        out = out + Q.reshape(m, n * n).T[:, :, None]
    else:
        out = np.empty((n * n, m, t))
        for k in range(m):
            out[:, k] = columns_matmul(ops[k], p_flat[:, k])
        out += Q.reshape(m, n * n).T[:, :, None]
    return x_pred, out.reshape(n, n, m, t)

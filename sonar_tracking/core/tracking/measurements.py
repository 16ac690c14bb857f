"""Checking a scan's measurements before they reach the tracker.

A row is dropped, with a :class:`Rejection` naming the row and the reason, when its position is
not finite, its covariance is not finite, not symmetric or not positive definite, or its clutter
density is not finite and positive (eqs. 32-33 divide by it). Dropping is per row: the rest of
the scan is used. Wrong shapes are a caller's bug and raise
:class:`~sonar_tracking.core.tracking.errors.TrackingInputError`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.jit import kernel
from sonar_tracking.core.tracking.errors import TrackingInputError

__all__ = ['Rejection', 'as_measurements', 'check_measurements']


@dataclass(frozen=True)
class Rejection:
    """Row ``index`` of the scan was dropped because of ``reason``."""

    index: int
    reason: str

    def __str__(self) -> str:
        return f'row {self.index}: {self.reason}'


def as_measurements(z, R=None, rho=None, *, default_R: np.ndarray | None = None,
                    default_rho: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(z (N, d), R (N, d, d), rho (N,))`` as float arrays, defaults filled in.

    ``R = None`` uses ``default_R (d, d)`` for every row and ``rho = None`` uses ``default_rho``.
    Raises TrackingInputError when a shape does not fit.
    """
    z = np.asarray(z, dtype=float)
    if z.ndim == 1 and z.size == 0:
        z = z.reshape(0, 2 if default_R is None else default_R.shape[0])
    if z.ndim != 2:
        raise TrackingInputError(f'z must have shape (N, d), got {z.shape}')
    n, d = z.shape
    if default_R is not None and d != default_R.shape[-1]:
        raise TrackingInputError(f'z has {d} columns; the tracker expects {default_R.shape[-1]}-D positions')
    if R is None:
        if default_R is None:
            raise TrackingInputError('R is None and no default measurement covariance is configured')
        R = np.broadcast_to(np.asarray(default_R, dtype=float), (n, d, d))
    else:
        R = np.asarray(R, dtype=float)
        if R.shape != (n, d, d):
            raise TrackingInputError(f'R must have shape ({n}, {d}, {d}) to match z, got {R.shape}')
    if rho is None:
        if default_rho is None:
            raise TrackingInputError('rho is None and no constant clutter density is configured')
        rho = np.full(n, float(default_rho))
    else:
        rho = np.asarray(rho, dtype=float)
        if rho.shape != (n,):
            raise TrackingInputError(f'rho must have shape ({n},) to match z, got {rho.shape}')
    return z, R, rho


def check_measurements(z: np.ndarray, R: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, list[Rejection]]:
    """Mask of usable rows and the reasons for the others (shapes as from :func:`as_measurements`).

    A covariance is symmetric when its off-diagonal pairs agree to 1e-9 of its largest entry,
    and positive definite when all its leading minors are positive (checked in closed form for
    2 x 2, by eigenvalues otherwise).
    """
    n, d = z.shape
    if n and d == 2 and R.strides[0] == 0 and _all_usable(z, R[0], rho):
        return np.ones(n, dtype=bool), []
    Rf = R.reshape(n, d * d)
    with np.errstate(invalid='ignore', over='ignore'):
        if d == 2:
            finite, sym, pd = np.empty(n, bool), np.empty(n, bool), np.empty(n, bool)
            _check_2d(z, np.ascontiguousarray(Rf), finite, sym, pd)
        else:
            finite = np.isfinite(z).all(axis=1) & np.isfinite(Rf).all(axis=1)
            Rs = np.where(finite[:, None, None], R, 0.0)
            sym = (np.abs(Rs - Rs.swapaxes(1, 2)).reshape(n, -1).max(axis=1, initial=0.0)
                   <= 1e-9 * np.abs(Rs).reshape(n, -1).max(axis=1, initial=0.0))
            pd = np.linalg.eigvalsh(0.5 * (Rs + Rs.swapaxes(1, 2))).min(axis=1, initial=0.0) > 0 if n else sym
        keep = finite & sym & pd & (rho > 0) & np.isfinite(rho)
    if keep.all():
        return keep, []
    rejections = []
    pos_ok = np.isfinite(z).all(axis=1)
    r_ok = np.isfinite(Rf).all(axis=1)
    for i in np.flatnonzero(~keep):
        if not pos_ok[i]:
            reason = f'position {z[i].tolist()} is not finite'
        elif not r_ok[i]:
            reason = f'covariance {R[i].tolist()} is not finite'
        elif not sym[i]:
            reason = f'covariance {R[i].tolist()} is not symmetric'
        elif not pd[i]:
            reason = f'covariance {R[i].tolist()} is not positive definite'
        else:
            reason = f'clutter density {float(rho[i])!r} must be finite and > 0'
        rejections.append(Rejection(int(i), reason))
    return keep, rejections


@kernel
def _check_2d(z, Rf, finite, sym, pd):
    """Per row of ``z (N, 2)`` and ``Rf (N, 4)`` (flattened 2 x 2 covariances ``a, b1, b2, c``):
    all six numbers finite, ``|b1 - b2| <= 1e-9 max(|a|, |c|)``, and ``a > 0``, ``a c - b1 b2 > 0``
    (compiled)."""
    for i in range(z.shape[0]):
        a, b1, b2, c = Rf[i, 0], Rf[i, 1], Rf[i, 2], Rf[i, 3]
        finite[i] = (np.isfinite(z[i, 0]) and np.isfinite(z[i, 1]) and np.isfinite(a) and np.isfinite(b1)
                     and np.isfinite(b2) and np.isfinite(c))
        sym[i] = abs(b1 - b2) <= 1e-9 * max(abs(a), abs(c))
        pd[i] = a > 0 and a * c - b1 * b2 > 0


def _all_usable(z: np.ndarray, R: np.ndarray, rho: np.ndarray) -> bool:
    """True when every row passes :func:`check_measurements` and all rows share the 2 x 2 ``R``
    (a broadcast covariance, the usual case): one matrix to check, the same tests in float64.
    False means "not sure": the row-by-row check decides."""
    a, b1, b2, c = R.ravel().tolist()
    if not (math.isfinite(a) and math.isfinite(b1) and math.isfinite(b2) and math.isfinite(c)):
        return False
    if not (abs(b1 - b2) <= 1e-9 * max(abs(a), abs(c)) and a > 0 and a * c - b1 * b2 > 0):
        return False
    # A finite sum means every entry is finite (an overflow only sends the scan to the full check).
    return math.isfinite(np.add.reduce(z, axis=None) + np.add.reduce(rho)) and np.minimum.reduce(rho) > 0

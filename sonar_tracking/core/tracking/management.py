"""Track management: one-point initiation, confirmation, termination, duplicates, a cap.

Initiation (one-point, with a velocity prior). Every measurement that no confirmed track
validated (eq. 25) starts a tentative track at the measurement with velocity mean zero and
variance ``speed_max^2 / 3`` per component (the moments of a component uniform on
``[-speed_max, speed_max]``; Musicki & Song, "Track initialization: prior target velocity and
acceleration moments", IEEE TAES 2013). We chose it over two-point differencing because:

* IPDA already decides whether a track follows a target: its existence probability (eqs. 24,
  33, 40) is the track quality measure of the paper, and one-point starts give it every
  measurement at once, with no second, ad hoc pairing gate;
* two-point starts pair every unused measurement with every unused one of the previous scan
  within ``speed_max * dt``; in dense clutter that multiplies tentative tracks and needs a
  buffer of held measurements, while one-point starts create exactly one track per unused
  measurement and need no memory;
* ``P_{0|0} = diag(R, speed_max^2/3 I)`` is well defined, which false-track discrimination
  (eqs. 47-48) needs.

Confirmation: a track is confirmed the first time its existence exceeds ``T_c`` and stays
confirmed until it is terminated (the paper's FTD counts confirmed tracks per scan). Termination:
existence below the lower threshold.

Duplicates (not in the paper). While the first track on a target is still tentative, the
target's next measurements are not used by a confirmed track and start more tracks on the
same target. A track whose combined state lies within ``merge_threshold`` (squared Mahalanobis
distance with the two covariances summed) of a confirmed track is removed: a tentative duplicate
of a confirmed track goes, and of two confirmed duplicates the younger one, so the id a user
sees stays on the target. The check runs when a track is confirmed (duplicates are born before
that) and, among confirmed tracks, on every scan.
"""
from __future__ import annotations

import numpy as np

__all__ = ['initial_covariance', 'one_point_initiation', 'unused_measurements', 'duplicate_tracks',
           'excess_tracks']


def initial_covariance(R: np.ndarray, speed_max: float) -> np.ndarray:
    """``P_{0|0} = diag(R, speed_max^2 / 3 I)`` for measurement covariances ``R (..., d, d)``."""
    R = np.asarray(R, dtype=float)
    d = R.shape[-1]
    P = np.zeros(R.shape[:-2] + (2 * d, 2 * d))
    P[..., :d, :d] = R
    idx = np.arange(d, 2 * d)
    P[..., idx, idx] = speed_max ** 2 / 3.0
    return P


def one_point_initiation(z: np.ndarray, R: np.ndarray, speed_max: float, n_modes: int
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Mode-conditioned states ``(2d, M, K)`` and covariances ``(2d, 2d, M, K)`` of K new tracks.

    ``z (K, d)``, ``R (K, d, d)``; every mode starts from the same state, ``P_{0|0}`` of
    :func:`initial_covariance` (tracks last, as in :mod:`~sonar_tracking.core.tracking.imm`).
    """
    k, d = z.shape
    x = np.zeros((2 * d, n_modes, k))
    x[:d] = z.T[:, None, :]
    P = np.zeros((2 * d, 2 * d, n_modes, k))
    P[:d, :d] = R.transpose(1, 2, 0)[:, :, None, :]
    idx = np.arange(d, 2 * d)
    P[idx, idx] = speed_max ** 2 / 3.0
    return x, P


def unused_measurements(n_meas: int, pair_track: np.ndarray, pair_meas: np.ndarray,
                        confirmed: np.ndarray) -> np.ndarray:
    """Mask of measurements that no confirmed track validated (these start new tracks)."""
    used = np.zeros(n_meas, dtype=bool)
    used[pair_meas[confirmed[pair_track]]] = True
    return ~used


def duplicate_tracks(x: np.ndarray, P: np.ndarray, existence: np.ndarray, confirmed: np.ndarray,
                     ids: np.ndarray, threshold: float) -> np.ndarray:
    """Mask of tracks to remove as duplicates of a confirmed track (see the module docstring).

    ``x (n, T)``, ``P (n, n, T)`` are the combined estimates (eqs. 41-42). Candidates are first
    screened on position alone (a marginal Mahalanobis distance never exceeds the full one), so
    the full test runs on few pairs.
    """
    n = x.shape[1]
    drop = np.zeros(n, dtype=bool)
    conf = np.flatnonzero(confirmed)
    if threshold <= 0 or len(conf) == 0 or n < 2:
        return drop
    dx = x[0][None, :] - x[0, conf][:, None]                            # (C, T)
    dy = x[1][None, :] - x[1, conf][:, None]
    a = P[0, 0][None, :] + P[0, 0, conf][:, None]
    b = P[0, 1][None, :] + P[0, 1, conf][:, None]
    c = P[1, 1][None, :] + P[1, 1, conf][:, None]
    with np.errstate(divide='ignore', invalid='ignore'):
        d2 = (c * dx * dx - 2 * b * dx * dy + a * dy * dy) / (a * c - b * b)
    near = (d2 < threshold) & (conf[:, None] != np.arange(n)[None, :])
    ci, tj = np.nonzero(near)
    if len(ci) == 0:
        return drop
    ci = conf[ci]
    diff = (x[:, ci] - x[:, tj]).T
    S = np.moveaxis(P[:, :, ci] + P[:, :, tj], -1, 0)
    full = np.linalg.solve(S, diff[..., None])[..., 0]
    dup = np.einsum('ki,ki->k', diff, full) < threshold
    ci, tj = ci[dup], tj[dup]
    # Keep the confirmed track, and of two confirmed ones the older (its id stays on the target).
    cc, ct = confirmed[ci], confirmed[tj]
    c_wins = (cc & ~ct) | ((cc == ct) & (ids[ci] < ids[tj]))
    drop[np.where(c_wins, tj, ci)] = True
    return drop


def excess_tracks(existence: np.ndarray, confirmed: np.ndarray, max_tracks: int) -> np.ndarray:
    """Mask of the least likely tentative tracks beyond ``max_tracks``."""
    drop = np.zeros(len(existence), dtype=bool)
    excess = len(existence) - max_tracks
    if excess <= 0:
        return drop
    order = np.lexsort((existence, confirmed))  # tentative first, lowest existence first
    drop[order[:excess]] = True
    return drop

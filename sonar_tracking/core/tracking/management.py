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

Gated initiation (not in the paper). In dense clutter one-point starts flood: every unused
measurement becomes a track whose first gate holds ``rho A`` clutter measurements, so pairs grow
as clutter^2. An unused measurement starts a track only where :func:`initiation_ratio` (the
expected gain of the target term of eq. 33 over the clutter-only ``E[Lambda] = 1`` in the new
track's first gate) is at least ``init.min_ratio``; this bounds the expected clutter in a new
gate to ``gamma P_D / (4 min_ratio)`` whatever the density, and so makes the pairs linear in the
clutter. Where the ratio is lower, an IPDA track could not tell its target from clutter anyway.
New tracks are also limited to the room left under ``track.max_tracks``, highest ratio first.

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

from .gating import budgeted_pairs

__all__ = ['initial_covariance', 'one_point_initiation', 'unused_measurements', 'duplicate_tracks',
           'initiation_ratio', 'excess_tracks']


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
                     ids: np.ndarray, threshold: float, max_pairs: int | None = None) -> np.ndarray:
    """Mask of tracks to remove as duplicates of a confirmed track (see the module docstring).

    ``x (n, T)``, ``P (n, n, T)`` are the combined estimates (eqs. 41-42). Candidates are
    screened spatially first with the gating index
    (:func:`~sonar_tracking.core.tracking.gating.budgeted_pairs`): along each position axis j a
    duplicate lies within ``sqrt(threshold (P_jj + max_c P^c_jj))`` of a confirmed track (a
    marginal Mahalanobis distance never exceeds the full one), so the work follows the near
    pairs, not confirmed x all tracks; the full test runs on those. At most ``max_pairs``
    candidate pairs are tested per call (youngest tracks first); tracks beyond wait for the next.
    """
    n = x.shape[1]
    drop = np.zeros(n, dtype=bool)
    conf = np.flatnonzero(confirmed)
    if threshold <= 0 or len(conf) == 0 or n < 2:
        return drop
    d = x.shape[0] // 2
    pos_var = np.stack([P[j, j] for j in range(d)])                    # (d, T)
    with np.errstate(invalid='ignore'):
        half = np.sqrt(threshold * (pos_var + pos_var[:, conf].max(axis=1)[:, None])).T
    centre = x[:d].T
    tj, k, _ = budgeted_pairs(centre - half, centre + half, centre[conf], max_pairs, lambda: np.argsort(-ids))
    ci = conf[k]
    near = ci != tj
    ci, tj = ci[near], tj[near]
    if len(ci) == 0:
        return drop
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


def initiation_ratio(R: np.ndarray, rho: np.ndarray, speed_max: float, dt: float, p_detect: float) -> np.ndarray:
    """Target-to-clutter density ratio of the first gate of a track started at each measurement.

    A one-point track started from a measurement with covariance ``R_i`` has, one scan ``dt``
    later, the innovation covariance ``S_1 = 2 R_i + dt^2 speed_max^2 / 3 I`` (process noise
    neglected). The target's measurement then has the expected likelihood
    ``E[N(nu; 0, S_1)] = 1 / ((4 pi)^(d/2) sqrt(det S_1))``; times ``P_D`` and divided by the
    clutter density ``rho_i`` this is the expected gain of the target term of eq. (33) over
    the clutter-only value ``E[Lambda] = 1``. Returns ``(N,)``.
    """
    R = np.asarray(R, dtype=float)
    d = R.shape[-1]
    S = 2.0 * R + (dt * dt * speed_max ** 2 / 3.0) * np.eye(d)
    if d == 2:
        det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
    else:
        det = np.linalg.det(S)
    return p_detect / ((4.0 * np.pi) ** (d / 2.0) * np.sqrt(det) * rho)


def excess_tracks(existence: np.ndarray, confirmed: np.ndarray, max_tracks: int) -> np.ndarray:
    """Mask of the least likely tentative tracks beyond ``max_tracks``."""
    drop = np.zeros(len(existence), dtype=bool)
    excess = len(existence) - max_tracks
    if excess <= 0:
        return drop
    order = np.lexsort((existence, confirmed))  # tentative first, lowest existence first
    drop[order[:excess]] = True
    return drop

"""Track management: one-point initiation, confirmation, termination, duplicates, a cap.

Initiation (one-point, with a velocity prior). Every measurement that no track validated
(eq. 25; with ``init.exclude: confirmed``, the paper's rule: no confirmed track) starts a
tentative track at the measurement with velocity mean zero and
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

Which measurements start tracks (``init.exclude``, not in the paper). With ``confirmed`` a
measurement inside a tentative track's gate starts one more track, so every clutter detection
does: tentative tracks grow with the clutter and, their gates holding more detections the denser
it is, the pairs with its square. With ``all`` (the default) a measurement some track already
validated starts none: that track is already testing the hypothesis that a target is there, and
PDA moves it to the target if one is. Tentative tracks then cover the surveillance area once
(about its area over a new track's gate area, however dense the clutter), and the pairs grow
with the clutter. Measured on the paper's scenarios, in docs/benchmarks/tracker_scaling.md.

Initiation budget (not in the paper). One-point initiation starts a track on every unused
detection, and each new track's gate is wide (the velocity prior), so in dense clutter the next
scan pairs T = N tracks with many detections each: work grows with the square of the clutter.
At most ``init.max_per_scan`` tracks start per scan. When more detections are unused, the ones
that start tracks are chosen by how likely they are to be a new target:

1. detections that no track (tentative or confirmed) validated come first: one inside a
   tentative track's gate is already being followed as a possible target;
2. then the lowest clutter density ``rho`` (SCMDE): IPDA's existence update (eqs. 33, 40) grows
   with ``p / rho``, so a track born in dense clutter is the least likely to be confirmed;
3. then the detection order (the detector lists the strongest first).

When fewer detections are unused than the budget (the paper's scenarios), every one starts a
track, which is the paper's one-point initiation.

Caps (not in the paper). After initiation, at most ``track.max_tracks`` tracks are kept (the
least likely tentative ones go, :func:`excess_tracks`). Before the update, the candidate pairs
(detections inside a track's gate box) are counted; beyond ``track.max_pairs`` the tracks with
the most candidates are dropped, tentative before confirmed (:func:`pair_budget`): a gate holding
many detections carries little information about a target, and the IPDA's existence of such a
track barely moves (without a target, eq. 33 gives ``E[Lambda] = 1``, so in clutter a tentative
track lives ``ln(initial/terminate) / -ln(survival)`` scans, 35 with the defaults). The cap is
on pairs rather than on tentative tracks because pairs are what cost: a wide sector with
hundreds of sparse clutter detections per scan (the paper's Scenario 1 at tau = 2) keeps
thousands of tentative tracks but only about 2,000 pairs, and is not touched. Together the
budget and the caps bound the tracks, the pairs and so the memory and time of a scan for any
input.

Confirmation: a track is confirmed the first time its existence exceeds ``T_c`` (with
``existence.confirm_distance`` d > 0, not in the paper: and its estimate has moved d from where its
existence first exceeded ``T_c``, so a static echo detected every frame, frozen speckle of an imaging
sonar or a rock, stays tentative; when a tentative track's existence falls below
``existence.confirm_lapse`` (1/2 by default: more likely gone than there), that point is forgotten
and taken again where its existence next exceeds ``T_c``, so a track that loses one still echo and
picks up another nearby has not moved) and stays confirmed
until it is terminated (the paper's FTD counts confirmed tracks per scan). Termination: existence
below the lower threshold.

Duplicates (not in the paper). While the first track on a target is still tentative, the
target's next measurements are not used by a confirmed track and start more tracks on the
same target. A track whose combined state lies within ``merge_threshold`` (squared Mahalanobis
distance with the two covariances summed) of a confirmed track is removed: a tentative duplicate
of a confirmed track goes, and of two confirmed duplicates the younger one, so the id a user
sees stays on the target. The check runs when a track is confirmed (duplicates are born before
that) and, among confirmed tracks, on every scan. Candidates are found with the gating's box
search (each track's box holds every state within the threshold of it), so the cost follows the
nearby pairs, not confirmed x all tracks.
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.jit import kernel
from sonar_tracking.core.tracking.gating import BoxSearch

__all__ = ['initial_covariance', 'initial_state_into', 'renew_tracks', 'unused_measurements', 'birth_measurements',
           'duplicate_tracks', 'excess_tracks', 'pair_budget', 'assess_tracks']


def initial_covariance(R: np.ndarray, speed_max: float) -> np.ndarray:
    """``P_{0|0} = diag(R, speed_max^2 / 3 I)`` for measurement covariances ``R (..., d, d)`` (eq. 48)."""
    R = np.asarray(R, dtype=float)
    d = R.shape[-1]
    flat = np.ascontiguousarray(R.reshape(-1, d, d))
    k = len(flat)
    x, P = np.empty((2 * d, 1, k)), np.empty((2 * d, 2 * d, 1, k))
    _initial_states(np.zeros((k, d)), flat, speed_max ** 2 / 3.0, x, P)
    return np.moveaxis(P[:, :, 0], -1, 0).reshape(R.shape[:-2] + (2 * d, 2 * d))


@kernel
def initial_state_into(z, R, k, speed_var, x, P, col):
    """One-point initiation (eqs. 47-48) of measurement ``k`` of ``z (K, d)``, ``R (K, d, d)`` into
    column ``col`` of ``x (2d, M, T)``, ``P (2d, 2d, M, T)``, the same for every mode: position
    ``z_k``, velocity 0; ``P_{0|0} = diag(R_k, speed_var I)`` (``speed_var = speed_max^2 / 3``)."""
    d = z.shape[1]
    for m in range(x.shape[1]):
        for i in range(2 * d):
            x[i, m, col] = z[k, i] if i < d else 0.0
            for j in range(2 * d):
                if i < d and j < d:
                    P[i, j, m, col] = R[k, i, j]
                else:
                    P[i, j, m, col] = speed_var if i == j else 0.0


@kernel
def _initial_states(z, R, speed_var, x, P):
    for k in range(len(z)):
        initial_state_into(z, R, k, speed_var, x, P, k)


@kernel
def renew_tracks(keep, x, P, mu, existence, confirmed, xc, Pc, z, R, speed_var, initial_existence,
                 x2, P2, mu2, existence2, confirmed2, xc2, Pc2):
    """The tracks ``keep`` (bool mask) of the per-track arrays, in order, then one new tentative
    track per row of ``z``, ``R`` (:func:`initial_state_into`, mode probabilities equal, existence
    ``initial_existence``), written into the arrays ending in 2 (compiled; one pass for the whole
    rebuild a scan needs)."""
    n, n_modes, n_tracks = x.shape
    q = 0
    for t in range(n_tracks):
        if not keep[t]:
            continue
        for i in range(n):
            xc2[i, q] = xc[i, t]
            for j in range(n):
                Pc2[i, j, q] = Pc[i, j, t]
            for m in range(n_modes):
                x2[i, m, q] = x[i, m, t]
                for j in range(n):
                    P2[i, j, m, q] = P[i, j, m, t]
        for m in range(n_modes):
            mu2[m, q] = mu[m, t]
        existence2[q] = existence[t]
        confirmed2[q] = confirmed[t]
        q += 1
    for k in range(len(z)):
        col = q + k
        initial_state_into(z, R, k, speed_var, x2, P2, col)
        for m in range(n_modes):
            mu2[m, col] = 1.0 / n_modes
        existence2[col] = initial_existence
        confirmed2[col] = False
        for i in range(n):
            xc2[i, col] = x2[i, 0, col]
            for j in range(n):
                Pc2[i, j, col] = P2[i, j, 0, col]


def unused_measurements(n_meas: int, pair_track: np.ndarray, pair_meas: np.ndarray,
                        tracks: np.ndarray | None = None) -> np.ndarray:
    """Mask of measurements that no track in the mask ``tracks`` (None: any track) validated
    (these may start tracks)."""
    used = np.zeros(n_meas, dtype=bool)
    used[pair_meas if tracks is None else pair_meas[tracks[pair_track]]] = True
    return ~used


# Up to this many (confirmed, track) combinations the position test runs on all of them.
_DENSE_DUPLICATES = 4096


def birth_measurements(unused: np.ndarray, validated: np.ndarray, rho: np.ndarray, budget: int) -> np.ndarray:
    """Indices (ascending) of the unused measurements that start tracks, at most ``budget``.

    ``unused (N,)`` bool (:func:`unused_measurements`), ``validated`` measurement indices of the
    scan's validated pairs (any track), ``rho (N,)`` clutter densities. The order of preference
    is in the module docstring.
    """
    idx = unused.nonzero()[0]
    if len(idx) <= budget:
        return idx
    seen = np.zeros(len(unused), dtype=bool)
    seen[validated] = True
    order = np.lexsort((idx, rho[idx], seen[idx]))
    return np.sort(idx[order[:budget]])


def pair_budget(counts: np.ndarray, confirmed: np.ndarray, max_pairs: int) -> np.ndarray:
    """Mask of tracks to drop so the candidate pairs ``counts (T,)`` sum to at most ``max_pairs``.

    Tentative tracks go before confirmed ones, and within each the tracks with the most
    candidates first.
    """
    drop = np.zeros(len(counts), dtype=bool)
    excess = int(counts.sum()) - max_pairs
    if excess <= 0:
        return drop
    order = np.lexsort((-counts, confirmed))
    n_drop = int(np.searchsorted(np.cumsum(counts[order]), excess, side='left')) + 1
    drop[order[:n_drop]] = True
    return drop


def duplicate_tracks(x: np.ndarray, P: np.ndarray, existence: np.ndarray, confirmed: np.ndarray,
                     ids: np.ndarray, threshold: float, max_pairs: int | None = None) -> np.ndarray:
    """Mask of tracks to remove as duplicates of a confirmed track (see the module docstring).

    ``x (n, T)``, ``P (n, n, T)`` are the combined estimates (eqs. 41-42). Candidates are first
    screened in boxes (``|dx_j| <= sqrt(thr P_jj) + sqrt(thr P'_jj)`` is necessary for a
    duplicate, since a marginal Mahalanobis distance never exceeds the full one), then on
    position alone, so the full test runs on few pairs. With ``max_pairs``, the boxes of the
    oldest confirmed tracks are searched while their candidates (counted first) fit in it, at
    least one box; the others wait for the next call (tracks on one spot would otherwise make
    confirmed x all pairs).
    """
    n = x.shape[1]
    drop = np.zeros(n, dtype=bool)
    conf = confirmed.nonzero()[0]
    if threshold <= 0 or len(conf) == 0 or n < 2:
        return drop
    if len(conf) * n <= _DENSE_DUPLICATES:
        # Few tracks: every (confirmed, track) combination.
        ci, tj = np.repeat(conf, n), np.tile(np.arange(n), len(conf))
    else:
        pos = x[:2].T                                                       # (T, 2)
        half = np.sqrt(threshold * np.stack((P[0, 0], P[1, 1]), axis=1))   # (T, 2)
        reach = half[conf] + half.max(axis=0)
        lo, hi = pos[conf] - reach, pos[conf] + reach
        search = BoxSearch(lo, hi, pos)
        if max_pairs is not None:
            counts = search.counts()
            if counts.sum() > max_pairs:
                order = np.argsort(ids[conf], kind='stable')
                keep = np.sort(order[:max(1, int(np.count_nonzero(np.cumsum(counts[order]) <= max_pairs)))])
                conf, lo, hi = conf[keep], lo[keep], hi[keep]
                search = BoxSearch(lo, hi, pos)
        ci, tj = search.pairs()
        ci = conf[ci]
    dup = np.empty(len(ci), dtype=bool)
    if not _duplicate_pairs(x, P, ci, tj, float(threshold), dup):
        return drop
    ci, tj = ci[dup], tj[dup]
    # Keep the confirmed track, and of two confirmed ones the older (its id stays on the target).
    cc, ct = confirmed[ci], confirmed[tj]
    c_wins = (cc & ~ct) | ((cc == ct) & (ids[ci] < ids[tj]))
    drop[np.where(c_wins, tj, ci)] = True
    return drop


@kernel
def _duplicate_pairs(x, P, ci, tj, threshold, dup):
    """``dup[k]``: tracks ``ci[k]`` and ``tj[k]`` (distinct) are within ``threshold`` (squared
    Mahalanobis distance of their combined states, covariances summed); returns whether any is.
    The test on position alone comes first: it is necessary, and cheap."""
    n = x.shape[0]
    S = np.empty((n, n))
    diff = np.empty(n)
    found = False
    for k in range(len(ci)):
        c, t = ci[k], tj[k]
        dup[k] = False
        if c == t:
            continue
        dx, dy = x[0, t] - x[0, c], x[1, t] - x[1, c]
        a, b, e = P[0, 0, t] + P[0, 0, c], P[0, 1, t] + P[0, 1, c], P[1, 1, t] + P[1, 1, c]
        if not (e * dx * dx - 2 * b * dx * dy + a * dy * dy) / (a * e - b * b) < threshold:
            continue
        for i in range(n):
            diff[i] = x[i, c] - x[i, t]
            for j in range(n):
                S[i, j] = P[i, j, c] + P[i, j, t]
        y = np.linalg.solve(S, diff)
        d2 = 0.0
        for i in range(n):
            d2 += diff[i] * y[i]
        if d2 < threshold:
            dup[k] = True
            found = True
    return found


@kernel
def assess_tracks(xc, Pc, existence, confirmed, confirm, terminate, max_variance, alive):
    """Confirmation and termination of every track from its combined estimate (compiled).

    A track whose estimate is not finite (or whose position variance is not positive) is dropped;
    a finite tentative track with existence above ``confirm`` becomes confirmed (``confirmed`` is
    updated in place); a finite track stays ``alive`` while its existence is at least ``terminate``
    and the largest eigenvalue of its position covariance at most ``max_variance``. Returns the
    counts ``(dropped as not finite, newly confirmed, terminated)``.
    """
    n, n_tracks = xc.shape
    dropped = newly = ended = 0
    for t in range(n_tracks):
        pxx, pxy, pyy = Pc[0, 0, t], Pc[0, 1, t], Pc[1, 1, t]
        major = 0.5 * (pxx + pyy) + np.sqrt(0.25 * (pxx - pyy) ** 2 + pxy ** 2)     # largest eigenvalue
        # Every failure of finiteness shows in the position variance or the state sum.
        total = major + existence[t]
        var_min = Pc[0, 0, t]
        for i in range(n):
            total += xc[i, t]
            var_min = min(var_min, Pc[i, i, t])
            for j in range(n):
                total += Pc[i, j, t]
        finite = np.isfinite(total) and var_min > 0.0
        if not finite:
            dropped += 1
            alive[t] = False
            continue
        if not confirmed[t] and existence[t] > confirm:
            confirmed[t] = True
            newly += 1
        alive[t] = existence[t] >= terminate and major <= max_variance
        if not alive[t]:
            ended += 1
    return dropped, newly, ended


def excess_tracks(existence: np.ndarray, confirmed: np.ndarray, max_tracks: int) -> np.ndarray:
    """Mask of the least likely tentative tracks beyond ``max_tracks``."""
    drop = np.zeros(len(existence), dtype=bool)
    excess = len(existence) - max_tracks
    if excess <= 0:
        return drop
    order = np.lexsort((existence, confirmed))  # tentative first, lowest existence first
    drop[order[:excess]] = True
    return drop

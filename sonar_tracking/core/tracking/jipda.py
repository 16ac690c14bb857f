"""Joint IPDA association (IMM-JIPDA) as per-pair clutter densities for the IPDA update.

JIPDA: D. Musicki and R. Evans, "Joint integrated probabilistic data association: JIPDA", IEEE
Trans. Aerospace and Electronic Systems 40(3), 2004; the IMM form mixes each track's modes into
one likelihood per measurement, ``p_{t,i} = sum_m mu^m_{k|k-1} p^m_{t,i}`` (ESC paper eq. 29).

Joint events. Track t has predicted existence ``psi_t`` (eq. 24) and, for each validated
measurement i, the likelihood ratio ``L_{t,i} = P_D P_G p_{t,i} / rho_i`` (eqs. 28-29, 32). A joint
event gives each track at most one measurement and each measurement at most one track; its weight
is ``prod_{t unassigned} (1 - psi_t P_D P_G) * prod_{t -> i} psi_t L_{t,i}`` (unassigned: the track
does not exist, ``1 - psi_t``, or exists and was missed, ``psi_t (1 - P_D P_G)``).

Marginals as a single-track IPDA. Let ``W_{-t}`` sum the weights of the events of the other tracks
of the cluster alone, and ``r_{t,i} = W_{-t}(events not using i) / W_{-t}(all events)``, in [0, 1].
Summing the joint events over the other tracks and dividing by ``W_{-t}(all)``, track t's
posterior weights are ``1 - psi_t`` (no target), ``psi_t (1 - P_D P_G)`` (missed) and
``psi_t L_{t,i} r_{t,i}`` (i is its detection). These are exactly the weights of a single-track
IPDA whose clutter density at i is ``rho_i / r_{t,i}``: its eq. (33)
``Lambda = 1 - P_D P_G + sum_i L_{t,i} r_{t,i}`` gives the JIPDA existence by eq. (40) and the
association probabilities by eq. (34). Per mode the same holds with ``p^m_{t,i}`` (eqs. 30-33),
since the other tracks enter only through ``r``, which does not depend on t's mode: the IMM mode
probabilities, mode estimates (eqs. 35-39) and combination (41-42) are the IPDA ones. So the
update is :func:`~sonar_tracking.core.tracking.ipda.ipda_update` with ``rho_i / r_{t,i}``.

Clusters. Tracks linked through shared validated measurements (connected components of the
track-measurement graph) are independent of one another; a track alone in its cluster has
``r = 1`` (the IPDA). A measurement validated by one track only (private) can be folded into that
track's "unassigned" weight, ``u'_t = 1 - psi_t P_D P_G + sum_{private i} psi_t L_{t,i}``, as no
other track competes for it; its ``r`` is 1.

Exact ``r`` (clusters of at most ``max_cluster`` tracks): a forward-backward recursion over the
cluster's shared measurements whose state is the set of tracks already assigned (``2^K`` states
for K tracks): ``F_j(A)`` sums the assignments of measurements ``< j`` to exactly the tracks in A,
``B_j(C)`` those of measurements ``>= j`` to tracks outside C times ``u'`` of the tracks left
unassigned. Then ``W_{-t}(not i) = sum_{A not containing t} F_i(A) B_{i+1}(A + t)`` and
``W_{-t}(all) = sum_{A not containing t} F_J(A) B_J(A + t)``: sums of positive terms, no
differences. Each track's weights are scaled by one constant first (``r`` does not change), so
the products stay in range. Work: O(J K 2^K) per cluster of J shared measurements; clusters of
one size are computed together, and two-track clusters in closed form, ``r_{t,i} = 1 - w_{s,i} / W_s``
with ``W_s = u'_s + sum_j w_{s,j}`` over the shared measurements.

Above ``max_cluster`` tracks, ``r_{t,i} ~ prod_{s != t} (1 - q_{s,i})``, with ``q_{s,i}`` track s's
independent IPDA probability that it exists and i is its detection (``beta_{s,i}`` of eq. 34 times
its existence, eq. 40): the
other tracks take i independently of one another, the idea of LM-IPDA (D. Musicki and
S. La Scala, "Multi-target tracking in clutter without measurement assignment", IEEE TAES 44(3),
2008). With two tracks this is exact (``r = 1 - q_{s,i}``). With more, it treats the other tracks'
claims on i as independent events where they are exclusive, and takes each claim from that track's
own IPDA, which ignores that the others compete for its measurements as well: on random clusters
of 3-6 tracks sharing 2-5 detections densely its existence and association probabilities are off
by 0.08 on average (docs/experiments/2026-11-25-jipda.md).

A degenerate cluster whose other tracks have no event of positive weight (``P_D P_G = 1``, existence
1 and nothing else to take) gets ``r = 1`` for those pairs.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sonar_tracking.core.tracking.errors import TrackingInputError
from sonar_tracking.core.tracking.gating import Innovations
from sonar_tracking.core.tracking.ipda import likelihood_ratios, segment_sum

# Most states of the exact recursion (clusters x shared detections x 2^K) computed at once (32 MB).
_DP_CELLS = 1 << 22

__all__ = ['AssociationFactors', 'pair_likelihoods', 'track_clusters', 'association_factors', 'exact_factors']


@dataclass(frozen=True)
class AssociationFactors:
    """``r (P,)`` per validated pair, and the clusters of the scan (tracks sharing measurements)."""

    r: np.ndarray
    clusters: int = 0         # clusters of two or more tracks
    largest: int = 0          # tracks in the largest cluster (0 without pairs)
    approximated: int = 0     # clusters above the limit (LM-IPDA approximation)


def pair_likelihoods(mu_pred: np.ndarray, track: np.ndarray, innov: Innovations, in_gate: np.ndarray,
                     rho: np.ndarray, p_detect: float, p_gate: float) -> np.ndarray:
    """``L_{t,i} = P_D P_G p_{t,i} / rho_i`` per pair, ``p_{t,i}`` mode-mixed by ``mu_pred (M, T)`` (eqs. 28-29)."""
    a = likelihood_ratios(innov, in_gate, rho, p_gate)                 # p^m_i / rho_i, (M, P)
    return (p_detect * p_gate) * np.einsum('mp,mp->p', np.take(mu_pred, track, axis=1), a)


def track_clusters(track: np.ndarray, meas: np.ndarray, n_tracks: int, n_meas: int) -> np.ndarray:
    """``(T,)`` cluster label of each track: connected components of tracks linked by a shared measurement.

    The label is the smallest track index of the component. Each round gives every track the
    smallest label among the tracks sharing a measurement with it, hooks its old label's track to
    that too, and follows labels to their end (pointer jumping), so a chain of n tracks takes about
    log n rounds of a few numpy calls over the pairs."""
    labels = np.arange(n_tracks)
    if len(track) == 0:
        return labels
    while True:
        m_label = np.full(n_meas, n_tracks)
        np.minimum.at(m_label, meas, labels[track])
        new = labels.copy()
        np.minimum.at(new, track, m_label[meas])
        if np.array_equal(new, labels):
            return labels
        np.minimum.at(new, labels, new)             # hook: a label's own track takes the smaller label
        while True:
            jumped = new[new]
            if np.array_equal(jumped, new):
                break
            new = jumped
        labels = new


@lru_cache(maxsize=16)
def _mask_tables(k: int) -> tuple[np.ndarray, np.ndarray]:
    """For ``2^k`` track sets: ``bit (k, 2^k)`` (t is in the set) and ``flip (k, 2^k)`` (the set with t toggled)."""
    masks = np.arange(1 << k)
    shifts = np.arange(k)[:, None]
    return ((masks >> shifts) & 1).astype(bool), masks ^ (1 << shifts)


def exact_factors(weight: np.ndarray, unassigned: np.ndarray) -> np.ndarray:
    """Exact ``r (..., K, J)`` of clusters of K tracks: ``weight (..., K, J)`` = ``psi_t L_{t,j}`` on their
    shared measurements (0 where t does not validate j, or for padding), ``unassigned (..., K)`` =
    ``u'_t`` (module docstring). Leading axes are independent clusters, computed together."""
    weight, unassigned = np.asarray(weight, dtype=float), np.asarray(unassigned, dtype=float)
    single = weight.ndim == 2
    if single:
        weight, unassigned = weight[None], unassigned[None]
    n_c, k, n_j = weight.shape
    if k == 2:
        r = _two_track_factors(weight, unassigned)
        return r[0] if single else r
    scale = np.maximum(unassigned, weight.max(axis=2, initial=0.0))
    scale = np.where(scale > 0.0, 1.0 / np.where(scale > 0.0, scale, 1.0), 1.0)
    w, u = weight * scale[:, :, None], unassigned * scale
    bit, flip = _mask_tables(k)
    free = ~bit
    F = np.zeros((n_j + 1, n_c, 1 << k))
    F[0, :, 0] = 1.0
    for j in range(n_j):
        f = F[j]
        F[j + 1] = f + np.einsum('ctm,ctm->cm', w[:, :, j, None] * bit, f[:, flip])
    B = np.empty((n_j + 1, n_c, 1 << k))
    B[n_j] = np.prod(np.where(bit, 1.0, u[:, :, None]), axis=1)         # u' of the tracks left unassigned
    for j in range(n_j - 1, -1, -1):
        b = B[j + 1]
        B[j] = b + np.einsum('ctm,ctm->cm', w[:, :, j, None] * free, b[:, flip])
    r = np.ones((n_c, k, n_j))
    for t in range(k):
        sel = free[t]
        total = np.einsum('cm,cm->c', F[n_j][:, sel], B[n_j][:, flip[t, sel]])       # W_{-t}(all)
        g = np.einsum('jcm,jcm->cj', F[:n_j][:, :, sel], B[1:][:, :, flip[t, sel]])  # W_{-t}(not j)
        ok = total > 0.0
        r[:, t] = np.where(ok[:, None], g / np.where(ok, total, 1.0)[:, None], 1.0)
    r = np.minimum(r, 1.0)
    return r[0] if single else r


def _two_track_factors(weight: np.ndarray, unassigned: np.ndarray) -> np.ndarray:
    """:func:`exact_factors` of two-track clusters in closed form: ``W_{-t}`` is the other track's
    ``u'_s + sum_j w_{s,j}``, so ``r_{t,i} = 1 - w_{s,i} / W_s`` (the error of the difference is
    rounding relative to 1)."""
    total = unassigned + weight.sum(axis=2)                           # (C, 2)
    other, w_other = total[:, ::-1, None], weight[:, ::-1]
    ok = other > 0.0
    return np.where(ok, np.clip((other - w_other) / np.where(ok, other, 1.0), 0.0, 1.0), 1.0)


def association_factors(track: np.ndarray, meas: np.ndarray, weight: np.ndarray, unassigned: np.ndarray,
                        max_cluster: int) -> AssociationFactors:
    """JIPDA factors ``r_{t,i}`` of the validated pairs (module docstring).

    ``track``, ``meas`` (P,) the pairs (sorted by track, each pair once), ``weight`` (P,)
    ``psi_t L_{t,i}`` (:func:`pair_likelihoods` times the predicted existence), ``unassigned`` (T,)
    ``1 - psi_t P_D P_G``. Clusters of at most ``max_cluster`` tracks are exact, larger ones use
    the LM-IPDA product.
    """
    n_pairs, n_tracks = len(track), len(unassigned)
    if max_cluster < 1:
        raise TrackingInputError(f'max_cluster = {max_cluster} must be >= 1')
    r = np.ones(n_pairs)
    if n_pairs == 0:
        return AssociationFactors(r=r)
    n_meas = int(meas.max()) + 1
    tracks_per_meas = np.bincount(meas, minlength=n_meas)
    shared = tracks_per_meas[meas] > 1
    if not shared.any():
        return AssociationFactors(r=r, largest=1)
    labels = track_clusters(track, meas, n_tracks, n_meas)
    sizes = np.bincount(labels)
    size_of_pair = sizes[labels[track]]
    multi = np.flatnonzero(sizes > 1)
    big = sizes[multi] > max_cluster
    # u'_t: private measurements fold into the unassigned weight.
    u_prime = unassigned + segment_sum(np.where(shared, 0.0, weight)[None], track, n_tracks)[0]
    if big.any():
        sel = shared & (size_of_pair > max_cluster)
        total = unassigned + segment_sum(weight[None], track, n_tracks)[0]
        with np.errstate(divide='ignore', invalid='ignore'):
            q = np.where(total[track] > 0.0, weight / np.where(total[track] > 0.0, total[track], 1.0), 0.0)
        r[sel] = _lm_product(meas[sel], np.clip(1.0 - q[sel], 0.0, 1.0), n_meas)
    exact_pairs = np.flatnonzero(shared & (size_of_pair <= max_cluster))
    if len(exact_pairs):
        r[exact_pairs] = _exact_by_size(track[exact_pairs], meas[exact_pairs], weight[exact_pairs], labels,
                                        sizes, u_prime, n_meas)
    return AssociationFactors(r=r, clusters=len(multi), largest=int(sizes.max()), approximated=int(big.sum()))


def _local_index(cluster: np.ndarray, item: np.ndarray, n_items: int) -> tuple[np.ndarray, np.ndarray]:
    """Index of each pair's ``item`` among the distinct items of its cluster, and those items' count per pair."""
    key = cluster.astype(np.int64) * n_items + item
    uniq, inv = np.unique(key, return_inverse=True)
    first = np.searchsorted(uniq, (uniq // n_items) * n_items)       # first distinct item of each cluster
    last = np.searchsorted(uniq, (uniq // n_items + 1) * n_items)
    return (np.arange(len(uniq)) - first)[inv], (last - first)[inv]


def _exact_by_size(track, meas, weight, labels, sizes, u_prime, n_meas) -> np.ndarray:
    """Exact ``r`` of the shared pairs of clusters within the limit, the clusters of one size together."""
    cl = labels[track]
    t_local, _ = _local_index(cl, track, len(labels))
    m_local, m_count = _local_index(cl, meas, n_meas)
    k_of = sizes[cl]
    out = np.ones(len(track))
    for k in np.unique(k_of):
        sel = np.flatnonzero(k_of == k)
        ids, c_of = np.unique(cl[sel], return_inverse=True)
        n_j = np.zeros(len(ids), dtype=np.intp)
        n_j[c_of] = m_count[sel]
        # Batches of clusters, fewest shared detections first, padded to the batch's largest:
        # at most _DP_CELLS recursion states per batch (one cluster at least).
        batch = np.zeros(len(ids), dtype=np.intp)
        n_batches = 1
        if len(ids) * (int(n_j.max()) + 1) << k > _DP_CELLS:
            order = np.argsort(n_j, kind='stable')
            first = 0
            for pos in range(len(order)):
                if pos > first and (pos - first + 1) * (int(n_j[order[pos]]) + 1) << k > _DP_CELLS:
                    n_batches, first = n_batches + 1, pos
                batch[order[pos]] = n_batches - 1
        for b in range(n_batches):
            if n_batches == 1:                                # every cluster of this size at once
                members, ps, c_local = np.arange(len(ids)), sel, c_of
            else:
                members = np.flatnonzero(batch == b)
                rank = np.full(len(ids), -1)
                rank[members] = np.arange(len(members))
                ps = sel[rank[c_of] >= 0]
                c_local = rank[c_of[rank[c_of] >= 0]]
            w = np.zeros((len(members), k, int(n_j[members].max())))
            w[c_local, t_local[ps], m_local[ps]] = weight[ps]
            u = np.zeros((len(members), k))
            u[c_local, t_local[ps]] = u_prime[track[ps]]
            out[ps] = exact_factors(w, u)[c_local, t_local[ps], m_local[ps]]
    return out


def _lm_product(meas: np.ndarray, keep: np.ndarray, n_meas: int) -> np.ndarray:
    """``prod_{s != t} keep_{s,i}`` for every pair (t, i), with zero factors counted apart (no 0/0)."""
    zero = keep <= 0.0
    log_keep = np.log(np.where(zero, 1.0, keep))
    n_zero = np.bincount(meas, weights=zero, minlength=n_meas)
    log_all = np.bincount(meas, weights=log_keep, minlength=n_meas)
    others_zero = n_zero[meas] - zero
    return np.where(others_zero > 0, 0.0, np.exp(log_all[meas] - log_keep))

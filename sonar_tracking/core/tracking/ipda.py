"""IMM-IPDA update, eqs. (28)-(40), for every track at once, each track an independent IPDA.

Inputs are the predicted mode filters of T tracks and the validated (track, measurement) pairs
of the scan with their innovation statistics (:mod:`~sonar_tracking.core.tracking.gating`).

Reading of the paper where it leaves a choice:

* Likelihood outside a mode's gate (eq. 28). ``p^m_{k,i} = N(z_i; H x^m, S^m_i) / P_G`` is the
  gate-truncated density, so it is zero for a measurement outside mode m's gate. A measurement
  in the gate of any mode is validated for the track (eq. 30 sums to ``M_k^m``, per mode), and
  ``p_{k,i}`` (eq. 29) mixes the modes it falls in.
* Per-measurement clutter density ``rho_{k,i}`` (eqs. 32-33): supplied by the caller (SCMDE) or
  a constant.
* ``p^{tau,p}_{k,i}`` in eq. (33) is ``p_{k,i}`` of eq. (29) (a typesetting slip).

Algebra used (equal to eqs. 30-35 term by term). With
``Lambda^m = 1 - P_D P_G + P_D P_G sum_i p^m_i / rho_i`` (eq. 33 for mode m alone),

* ``Lambda_k = sum_m mu^m_{k|k-1} Lambda^m`` (eq. 33, since ``p_i = sum_m mu^m p^m_i``, eq. 29);
* ``mu^m_{k|k} = mu^m_{k|k-1} Lambda^m / Lambda_k`` (eqs. 30-31);
* ``beta^m_{k,0} = (1 - P_D P_G) / Lambda^m`` and ``beta^m_{k,i} = P_D P_G p^m_i / (rho_i Lambda^m)``
  (eq. 34 with eqs. 31-32 substituted).

The mode posterior (eqs. 35-39, with eq. 36 in its standard form, see
:mod:`~sonar_tracking.core.tracking.gaussian`) is the PDA combination. With ``H = [I 0]``,
``P H^T`` is the first d columns of ``P``; with ``w_i = S_i^{-1} nu_i`` each hypothesis is
``x_i = x + P H^T w_i`` and ``P_i = P - P H^T S_i^{-1} H P`` (eqs. 37-39), so

``x^m = x + P H^T w_bar``, ``P^m = P + P H^T A P H^T`` with ``w_bar = sum_i beta_i w_i`` and
``A = sum_i beta_i (w_i w_i^T - S_i^{-1}) - w_bar w_bar^T``,

which is exactly the moment-matched mixture over ``i = 0 .. M_k^m`` (``x_0 = x``, ``P_0 = P``)
but needs only d x d work per pair. With one measurement, ``beta_1 = 1`` (``P_D P_G = 1``) it is
the Kalman filter update.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.jit import kernel
from sonar_tracking.core.tracking.errors import TrackingInputError
from sonar_tracking.core.tracking.gating import Innovations, normal_density
from sonar_tracking.core.tracking.markov import existence_posterior

__all__ = ['IpdaResult', 'likelihood_ratios', 'ipda_update', 'segment_sum']


@dataclass(frozen=True)
class IpdaResult:
    """Posterior of T tracks (tracks last): mode estimates, mode and existence probabilities, Lambda."""

    x: np.ndarray          # (n, M, T)    eq. (35)
    P: np.ndarray          # (n, n, M, T) eq. (36), standard form
    mu: np.ndarray         # (M, T)       eq. (30)
    existence: np.ndarray  # (T,)         eq. (40)
    lam: np.ndarray        # (T,)         eq. (33)
    lam_mode: np.ndarray   # (M, T)       eq. (33) per mode


# Below this many pairs one reduceat call is cheapest; above, one bincount per row is.
_REDUCEAT_MAX_PAIRS = 1000


def segment_sum(values: np.ndarray, segment: np.ndarray, n: int) -> np.ndarray:
    """Sum the columns of ``values (K, P)`` by ``segment (P,)`` id into ``(K, n)``.

    ``segment`` must be non-decreasing. Each sum adds its terms in order (no cumulative-sum
    differences), so small terms after large ones keep their precision.
    """
    k, p = values.shape
    if p == 0:
        return np.zeros((k, n))
    if p <= _REDUCEAT_MAX_PAIRS:
        out = np.zeros((k, n))
        first = np.empty(p, dtype=bool)                     # a segment's first pair
        first[0] = True
        np.not_equal(segment[1:], segment[:-1], out=first[1:])
        starts = first.nonzero()[0]
        out[:, segment[starts]] = np.add.reduceat(values, starts, axis=1)
        return out
    return np.stack([np.bincount(segment, weights=v, minlength=n) for v in values])


def likelihood_ratios(innov: Innovations, in_gate: np.ndarray, rho: np.ndarray, p_gate: float) -> np.ndarray:
    """``(M, P)`` ``p^m_i / rho_i``: eq. (28) per mode (zero outside the mode's gate) over the clutter
    density of eqs. (32)-(33)."""
    out = np.empty(in_gate.shape)
    _likelihood_ratios(innov.d2, innov.det, in_gate, rho, p_gate, (2.0 * math.pi) ** innov.nu.shape[0], out)
    return out


@kernel
def likelihood_ratio(inside, d2, det, norm, rho, p_gate):
    """One pair and mode of :func:`likelihood_ratios` (compiled scalar); ``norm = (2 pi)^d``."""
    a = normal_density(d2, det, norm) if inside else 0.0
    return a * (1.0 / (p_gate * rho))


@kernel
def _likelihood_ratios(d2, det, in_gate, rho, p_gate, norm, out):
    for m in range(in_gate.shape[0]):
        for p in range(in_gate.shape[1]):
            out[m, p] = likelihood_ratio(in_gate[m, p], d2[m, p], det[m, p], norm, rho[p], p_gate)


def ipda_update(x_pred: np.ndarray, P_pred: np.ndarray, mu_pred: np.ndarray, existence_pred: np.ndarray,
                track: np.ndarray, innov: Innovations, in_gate: np.ndarray, rho: np.ndarray,
                p_detect: float, p_gate: float) -> IpdaResult:
    """IMM-IPDA measurement update of T tracks (component-major arrays, tracks and pairs last).

    Parameters
    ----------
    x_pred, P_pred : ``(n, M, T)``, ``(n, n, M, T)`` predicted mode estimates (eqs. 22-23).
    mu_pred : ``(M, T)`` predicted mode probabilities (eq. 20).
    existence_pred : ``(T,)`` predicted existence (eq. 24).
    track : ``(P,)`` track index of each validated pair, non-decreasing.
    innov : innovation statistics of the pairs (``(..., M, P)``).
    in_gate : ``(M, P)`` bool, the pair's measurement is in mode m's gate (eq. 25).
    rho : ``(P,)`` clutter density at the pair's measurement [1/m^d], > 0.
    p_detect, p_gate : ``P_D`` and ``P_G``.
    """
    n_tracks, d = x_pred.shape[2], innov.nu.shape[0]
    if len(track) > 1 and np.count_nonzero(track[1:] < track[:-1]):
        raise TrackingInputError('ipda_update: pairs must be sorted by track')
    x, P = np.empty(x_pred.shape), np.empty(P_pred.shape)
    mu, lam_mode = np.empty(mu_pred.shape), np.empty(mu_pred.shape)
    existence, lam = np.empty(n_tracks), np.empty(n_tracks)
    _ipda_update(x_pred, P_pred, mu_pred, np.asarray(existence_pred, dtype=float), track, innov.s_inv, innov.w,
                 innov.d2, innov.det, in_gate, rho, float(p_detect), float(p_gate), (2.0 * math.pi) ** d,
                 x, P, mu, existence, lam, lam_mode)
    return IpdaResult(x=x, P=P, mu=mu, existence=existence, lam=lam, lam_mode=lam_mode)


@kernel
def _ipda_update(x_pred, P_pred, mu_pred, e_pred, track, s_inv, w, d2, det, in_gate, rho, p_detect, p_gate, norm,
                 x, P, mu, existence, lam, lam_mode):
    """:func:`ipda_update` into the given arrays (compiled; the algebra of the module docstring)."""
    n, n_modes, n_tracks = x_pred.shape
    d = w.shape[0]
    n_upper = d * (d + 1) // 2
    pdpg = p_detect * p_gate
    # Per track and mode, summed over its pairs in order: a, a w and a (w w^T - S^-1) (upper triangle).
    sums = np.zeros((1 + d + n_upper, n_modes, n_tracks))
    for p in range(len(track)):
        t = track[p]
        for m in range(n_modes):
            a = likelihood_ratio(in_gate[m, p], d2[m, p], det[m, p], norm, rho[p], p_gate)   # eq. (28) / rho_i
            sums[0, m, t] += a
            u = 1 + d
            for i in range(d):
                sums[1 + i, m, t] += a * w[i, m, p]
                for j in range(i, d):
                    sums[u, m, t] += a * (w[i, m, p] * w[j, m, p] - s_inv[i, j, m, p])
                    u += 1
    w_bar = np.empty(d)
    A = np.empty((d, d))
    pa = np.empty((n, d))
    for t in range(n_tracks):
        total = 0.0
        for m in range(n_modes):
            lam_mode[m, t] = (1.0 - pdpg) + pdpg * sums[0, m, t]                           # eq. (33), per mode
            total += mu_pred[m, t] * lam_mode[m, t]                                        # eq. (33)
        lam[t] = total
        for m in range(n_modes):
            weighted = mu_pred[m, t] * lam_mode[m, t]
            if pdpg < 1.0:                              # then every Lambda >= 1 - P_D P_G > 0
                mu[m, t] = weighted / total                                                # eqs. (30)-(31)
                coef = pdpg / lam_mode[m, t]                            # beta^m_i = coef p^m_i / rho_i
            else:
                # P_D P_G = 1: a mode with nothing in its gate has Lambda^m = 0 and no posterior; it
                # keeps its prediction (its probability is 0). With Lambda = 0 the track cannot exist.
                mu[m, t] = weighted / total if total > 0.0 else mu_pred[m, t]
                coef = pdpg / lam_mode[m, t] if lam_mode[m, t] > 0.0 else 0.0
            for i in range(d):
                w_bar[i] = coef * sums[1 + i, m, t]
            u = 1 + d
            for i in range(d):
                for j in range(i, d):
                    A[i, j] = coef * sums[u, m, t] - w_bar[i] * w_bar[j]
                    A[j, i] = A[i, j]
                    u += 1
            # x^m = x + P H^T w_bar and P^m = P + (P H^T) A (P H^T)^T; P H^T = first d columns of P.
            for i in range(n):
                s = 0.0
                for j in range(d):
                    s += P_pred[i, j, m, t] * w_bar[j]
                x[i, m, t] = x_pred[i, m, t] + s                                           # eqs. (35), (37)
                for k in range(d):
                    s = 0.0
                    for j in range(d):
                        s += P_pred[i, j, m, t] * A[j, k]
                    pa[i, k] = s
            # Not re-symmetrised: the asymmetry stays at rounding level (1e-16 relative), and every
            # consumer reads symmetric parts (the gate averages S_xy and S_yx).
            for i in range(n):
                for j in range(n):
                    s = 0.0
                    for k in range(d):
                        s += pa[i, k] * P_pred[j, k, m, t]
                    P[i, j, m, t] = P_pred[i, j, m, t] + s                                 # eqs. (36), (38)
        existence[t] = existence_posterior(e_pred[t], total)                               # eq. (40)

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

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .errors import TrackingInputError
from .gating import Innovations
from .markov import update_existence

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


@lru_cache(maxsize=8)
def _symmetric_indices(d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row and column of the upper-triangle entries of a d x d matrix, and ``(d, d)`` positions in that list."""
    iu, ju = np.triu_indices(d)
    sym = np.empty((d, d), dtype=np.intp)
    sym[iu, ju] = sym[ju, iu] = np.arange(len(iu))
    return iu, ju, sym


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
    a = np.where(in_gate, innov.density(), 0.0)
    a *= 1.0 / (p_gate * rho)
    return a


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
    n, n_modes, n_tracks = x_pred.shape
    d = innov.nu.shape[0]
    if len(track) > 1 and np.count_nonzero(track[1:] < track[:-1]):
        raise TrackingInputError('ipda_update: pairs must be sorted by track')
    pdpg = p_detect * p_gate
    a = likelihood_ratios(innov, in_gate, rho, p_gate)              # eq. (28) over rho_i (eqs. 32-33)
    w = innov.w
    iu, ju, sym = _symmetric_indices(d)
    # Per pair and mode: a, a w and a (w w^T - S^-1) (upper triangle), summed per track below.
    vals = np.concatenate((a[None], a * w, a * (w[iu] * w[ju] - innov.s_inv[iu, ju])))
    sums = segment_sum(vals.reshape(len(vals) * n_modes, -1), track, n_tracks)
    sums = sums.reshape(len(vals), n_modes, n_tracks)

    lam_mode = (1.0 - pdpg) + pdpg * sums[0]                        # eq. (33), per mode
    weighted = mu_pred * lam_mode
    lam = np.add.reduce(weighted, axis=0)                                 # eq. (33)
    if pdpg < 1.0:                                                  # then every Lambda >= 1 - P_D P_G > 0
        mu = weighted / lam                                         # eqs. (30)-(31)
        coef = pdpg / lam_mode                                      # beta^m_i = coef p^m_i / rho_i
    else:
        # P_D P_G = 1: a mode with nothing in its gate has Lambda^m = 0 and no posterior; it
        # keeps its prediction (its probability is 0). With Lambda = 0 the track cannot exist.
        ok = lam > 0.0
        mu = np.where(ok, weighted / np.where(ok, lam, 1.0), mu_pred)
        pos = lam_mode > 0.0
        coef = np.where(pos, pdpg / np.where(pos, lam_mode, 1.0), 0.0)
    scaled = coef * sums[1:]                                        # w_bar, then A's sum term
    w_bar = scaled[:d]
    A_upper = scaled[d:]
    A_upper -= w_bar[iu] * w_bar[ju]
    A = A_upper[sym]                                               # (d, d, M, T)
    # x^m = x + P H^T w_bar and P^m = P + (P H^T) A (P H^T)^T; P H^T = first d columns of P.
    pht = P_pred[:, :d]
    x = x_pred + np.einsum('ijmt,jmt->imt', pht, w_bar)             # eqs. (35), (37)
    # Not re-symmetrised: the asymmetry stays at rounding level (1e-16 relative), and every
    # consumer reads symmetric parts (the gate averages S_xy and S_yx).
    P = P_pred + np.einsum('ikmt,lkmt->ilmt', np.einsum('ijmt,jkmt->ikmt', pht, A), pht)  # eqs. (36), (38)
    existence = update_existence(existence_pred, lam)               # eq. (40)
    return IpdaResult(x=x, P=P, mu=mu, existence=existence, lam=lam, lam_mode=lam_mode)

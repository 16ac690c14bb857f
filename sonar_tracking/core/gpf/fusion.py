"""Fusing the cues' likelihoods: multiplicative (eq. 15), weighted (eq. 14), adaptive (eqs. 16-18).

Everything is in the log domain: ``log_p (m, K)`` holds ``ln p(y^i | x_n)`` of eq. (13) for m cues
and K particles, and the fused ``ln p(y^1..y^m | x_n)`` comes back ``(K,)``, so a product of many
small likelihoods never underflows and a weighted sum is a log-sum-exp. The functions also take
several tracks at once (leading dimensions, :func:`fuse_many`), with the same result per track.

**Cue spread (eqs. 16-17).** ``A_i`` is the covariance of the particles weighted by cue i's
likelihood normalised over the particles (eq. 16 uses ``p(y^i | x_n)`` as weights and as a mean,
which only makes sense when they sum to one), and ``Delta_i`` its Frobenius norm (eq. 17). We take
the *position* part of the state: a cue measures where the particle's window is, its weights
say nothing directly about velocity, and position and velocity covariances have different units,
so a Frobenius norm over both would add metres squared to metres squared per second squared.

**Reliability relative to the prior.** Eq. (18) compares ``1/Delta_i`` with a fixed ``T_i``. In
the paper's trackers the candidates were always drawn with the same spread around the previous
position (§5.1), so a fixed ``T_i`` was a fixed ratio to that spread. Our GPF draws its particles
from the predicted Gaussian, whose spread changes from frame to frame (it widens while a target
is lost): a fixed ``T_i`` would call every cue degenerate whenever the track is uncertain, and
weighted fusion, which concentrates the particles least, would keep it uncertain. So the
reliability we compare with ``T_i`` is ``Delta_0 / Delta_i``, with ``Delta_0`` the Frobenius norm
of the unweighted particles' position covariance: how many times cue i concentrates the
particles (1 = not at all); ``T_i`` is dimensionless. It is also the input of the fuzzy weights.

**Switch (eq. 18).** The paper writes the two branches with a per-cue condition but one fused
model; we read it as: multiplicative fusion when every cue is reliable (``1/Delta_i > T_i`` for
all i), weighted fusion as soon as one cue has degenerated (its weights no longer concentrate the
particles), which is the paper's "as a feature clue is good, MF ... otherwise, WF" (§4.2.2).

**A second target in the cloud (switch ``crossing``, the default).** §4.2.2 prefers MF while the
observation is unambiguous and WF once a cue can no longer be trusted. The per-cue test above sees
one kind of untrustworthy cue, a flat one; it does not see a cue that is sharp on the *wrong*
target. When another track's predicted position lies inside this track's particle cloud, the
other target's echo is among the windows the particles look at, and the templates of crossing
targets are alike (mean ``d^2`` 0.2-0.9 to the other target against 1.5-5 to background, seed 7):
every cue then concentrates the particles, eq. 18 says MF, and the product of eq. 15 sharpens onto
whichever target matches better, so the track swaps or coalesces. WF's sum (eq. 14) keeps both
modes weak and the motion prediction carries the track through. So adaptive fusion is WF whenever
another track's predicted position is within the squared Mahalanobis distance ``fusion.gate``
(9.21: 99 % of a 2-D Gaussian, i.e. inside the cloud the particles are drawn from) of this track's
predicted position, and eq. 18's per-cue test otherwise. Switch ``cues`` is eq. 18 alone.
The measurements behind this choice are in ``docs/experiments/2026-11-21-fls-gpf-study.md``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy.special import logsumexp

from sonar_tracking.core.gpf.fuzzy import fuzzy_weights

__all__ = ['MF', 'WF', 'second_target', 'normalise_log', 'cue_weights', 'cue_spreads', 'multiplicative', 'weighted',
           'Fused', 'fuse', 'fuse_many']

#: Values of GPF_TRACK_DTYPE's ``fusion`` field.
MF, WF = 0, 1


def normalise_log(log_w: np.ndarray, axis: int = -1) -> np.ndarray:
    """Weights ``exp(log_w)`` normalised along ``axis``; uniform where every entry is -inf or NaN."""
    lw = np.where(np.isnan(log_w), -np.inf, log_w)
    top = lw.max(axis=axis, keepdims=True)
    bad = ~np.isfinite(top)
    with np.errstate(over='ignore'):    # -1e308 - 1e308 is -inf: its weight is 0, as it should be
        w = np.exp(lw - np.where(bad, 0.0, top))
    w = np.where(bad, 1.0, w)
    return w / w.sum(axis=axis, keepdims=True)


def cue_weights(log_p: np.ndarray) -> np.ndarray:
    """Each cue's likelihood normalised over the particles, ``(..., m, K)`` (the weights of eq. 16)."""
    return normalise_log(log_p, axis=-1)


def cue_spreads(positions: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``Delta_i`` of eq. (17): Frobenius norm of ``A_i`` of eq. (16), the weighted covariance of the
    particle positions ``(..., K, d)`` under each cue's normalised weights ``(..., m, K)``; shape
    ``(..., m)``."""
    mean = weights @ positions                                  # (..., m, d)
    dev = positions[..., None, :, :] - mean[..., :, None, :]    # (..., m, K, d)
    A = np.einsum('...mk,...mka,...mkb->...mab', weights, dev, dev)
    return np.sqrt(np.sum(A * A, axis=(-2, -1)))


def multiplicative(log_p: np.ndarray) -> np.ndarray:
    """Eq. (15): ``ln prod_i p(y^i | x)`` per particle, ``(..., K)`` from ``(..., m, K)``."""
    return log_p.sum(axis=-2)


def weighted(log_p: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Eq. (14): ``ln sum_i a_i p(y^i | x)`` per particle, weights ``a (..., m)`` summing to one."""
    return logsumexp(log_p + np.log(np.asarray(a, dtype=np.float64))[..., None], axis=-2)


@dataclass(frozen=True)
class Fused:
    """Fused log-likelihood ``(K,)``, the fusion used (MF or WF), the weights ``a_i`` (WF; None for
    MF) and every cue's reliability ``Delta_0 / Delta_i``."""

    log_likelihood: np.ndarray
    mode: int
    a: np.ndarray | None
    inverse_spread: np.ndarray


def second_target(mean: np.ndarray, cov: np.ndarray, others: np.ndarray | None, gate: float) -> bool:
    """True when one of the ``others (N, 2)`` predicted positions lies inside the cloud of a track
    predicted at ``mean`` with position covariance ``cov (2, 2)``: squared Mahalanobis distance
    below ``gate`` (module docstring, switch ``crossing``)."""
    if others is None or len(others) == 0:
        return False
    dev = np.asarray(others, dtype=float).reshape(-1, 2) - np.asarray(mean, dtype=float)[:2]
    d2 = np.einsum('na,ab,nb->n', dev, np.linalg.pinv(np.asarray(cov, dtype=float)[:2, :2]), dev)
    return bool(np.any(d2 < gate))


def fuse(log_p: np.ndarray, positions: np.ndarray, thresholds: np.ndarray, mode: str = 'af',
         crowded: bool = False) -> Fused:
    """Fuse ``log_p (m, K)`` with ``mode`` ``'mf'``, ``'wf'`` or ``'af'`` (eq. 18), for particles at
    ``positions (K, d)`` and cue thresholds ``T_i`` ``(m,)`` on the reliability ``Delta_0 / Delta_i``
    (module docstring). ``crowded``: another target is inside the cloud (:func:`second_target`),
    so ``'af'`` is WF whatever the cues say."""
    return fuse_many(log_p[None], positions[None], thresholds, mode, np.array([crowded]))[0]


def fuse_many(log_p: np.ndarray, positions: np.ndarray, thresholds: np.ndarray, mode: str = 'af',
              crowded: np.ndarray | None = None) -> list[Fused]:
    """:func:`fuse` of n tracks at once: ``log_p (n, m, K)``, ``positions (n, K, d)``, ``crowded (n,)``."""
    if mode not in ('af', 'mf', 'wf'):
        raise ValueError(f'fusion mode {mode!r} must be af, mf or wf')
    n, k = positions.shape[:2]
    crowded = np.zeros(n, bool) if crowded is None else np.asarray(crowded, bool)
    prior = cue_spreads(positions, np.full((n, 1, k), 1.0 / k))[:, 0]
    inv = prior[:, None] / np.maximum(cue_spreads(positions, cue_weights(log_p)), 1e-300)
    use_mf = (~crowded & np.all(inv > np.asarray(thresholds), axis=1)) if mode == 'af' else np.full(n, mode == 'mf')
    out: list[Fused | None] = [None] * n
    mf = np.flatnonzero(use_mf)
    if mf.size:
        fused = multiplicative(log_p[mf])
        for j, i in enumerate(mf):
            out[i] = Fused(fused[j], MF, None, inv[i])
    wf = np.flatnonzero(~use_mf)
    if wf.size:
        a = fuzzy_weights(inv[wf], thresholds)
        fused = weighted(log_p[wf], a)
        for j, i in enumerate(wf):
            out[i] = Fused(fused[j], WF, a[j], inv[i])
    return cast(list[Fused], out)   # every track is MF or WF

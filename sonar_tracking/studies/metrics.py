"""Tracking performance measures: the ESC paper's (§5) and the set metrics OSPA and GOSPA.

ESC paper, §5.1:

* False-track discrimination (eqs. 47-48). A confirmed track with estimate ``x_hat`` is a
  *confirmed true track* (CTT) of a target with state ``x`` when
  ``(x - x_hat)^T P_{0|0}^{-1} (x - x_hat) < tau_True`` and a *confirmed false track* (CFT) when
  the distance exceeds ``tau_False`` (the paper: 40 and 20). ``P_{0|0}`` is the covariance the
  track was initialised with. With several targets, a track is true when it is within
  ``tau_True`` of some target and false when it is beyond ``tau_False`` of every target; a track
  in between is neither.
* CTTR = nCTT / M: per scan, the fraction of the M Monte Carlo runs in which the target has a
  confirmed true track (at most one counted per target and run; with several targets, also
  averaged over targets).
* Position RMSE (eq. 49): per scan, ``sqrt(mean (x~^2 + y~^2))`` over the runs in which the target
  has a CTT (the paper's M counts those runs); the target's CTT is its nearest one.
* Rate of CFT (Table 1): confirmed-false-track scans / (scans x Monte Carlo runs).

FLS paper, §5: the centre location error CLE (eq. 19), the Euclidean distance between a tracked
and the true centre, :func:`center_location_error`.

Set metrics, for comparing estimated and true target sets without the labels above:

* OSPA: D. Schuhmacher, B.-T. Vo and B.-N. Vo, "A consistent metric for performance evaluation
  of multi-object filters", IEEE Trans. Signal Processing 56(8), 2008.
* GOSPA: A. S. Rahmathullah, A. F. Garcia-Fernandez and L. Svensson, "Generalized optimal
  sub-pattern assignment metric", 20th Int. Conf. on Information Fusion (FUSION), 2017.

Both solve the optimal assignment with ``scipy.optimize.linear_sum_assignment``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ['TAU_TRUE', 'TAU_FALSE', 'MetricError', 'cft_scan_rate', 'paired_difference', 'ftd_distances',
           'TrackClasses', 'classify_tracks',
           'ScanEvaluation', 'evaluate_scan', 'confirmed_true_track_rate', 'position_rmse',
           'confirmed_false_track_rate', 'OspaResult', 'ospa', 'GospaResult', 'gospa', 'gospa_assignment',
           'center_location_error']

#: Thresholds of eqs. (47)-(48) used in the paper.
TAU_TRUE = 20.0
TAU_FALSE = 40.0

_STATE_FIELDS = ('x', 'y', 'vx', 'vy')


class MetricError(ValueError):
    """Arguments of a metric do not fit; the message says what was expected."""


def _points(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1 and a.size == 0:
        a = a.reshape(0, 1)
    if a.ndim != 2:
        raise MetricError(f'{name} must have shape (count, dim), got {a.shape}')
    return a


def ftd_distances(truth, estimates, P0) -> np.ndarray:
    """Left-hand side of eqs. (47)-(48): ``(x_g - x_hat_t)^T P0^{-1} (x_g - x_hat_t)``, shape ``(T, G)``.

    ``truth (G, n)`` target states, ``estimates (T, n)`` track states, ``P0`` the initial
    covariance, ``(n, n)`` shared or ``(T, n, n)`` per track.
    """
    truth, est = _points(truth, 'truth'), _points(estimates, 'estimates')
    if truth.shape[1] != est.shape[1] and len(truth) and len(est):
        raise MetricError(f'truth has {truth.shape[1]} state components, estimates {est.shape[1]}')
    P0 = np.asarray(P0, dtype=float)
    n = est.shape[1]
    if P0.shape not in ((n, n), (len(est), n, n)):
        raise MetricError(f'P0 must have shape ({n}, {n}) or ({len(est)}, {n}, {n}), got {P0.shape}')
    if len(truth) == 0 or len(est) == 0:
        return np.zeros((len(est), len(truth)))
    diff = truth[None, :, :] - est[:, None, :]                               # (T, G, n)
    inv = np.linalg.inv(P0)
    if inv.ndim == 2:
        return np.einsum('tgi,ij,tgj->tg', diff, inv, diff)
    return np.einsum('tgi,tij,tgj->tg', diff, inv, diff)


@dataclass(frozen=True)
class TrackClasses:
    """FTD labels of T tracks: ``label`` 1 true, -1 false, 0 neither; ``target`` nearest target (-1: none)."""

    label: np.ndarray
    target: np.ndarray
    distance: np.ndarray

    @property
    def n_true(self) -> int:
        return int(np.count_nonzero(self.label == 1))

    @property
    def n_false(self) -> int:
        return int(np.count_nonzero(self.label == -1))


def classify_tracks(truth, estimates, P0, tau_true: float = TAU_TRUE, tau_false: float = TAU_FALSE) -> TrackClasses:
    """False-track discrimination of confirmed tracks, eqs. (47)-(48)."""
    if not 0 < tau_true <= tau_false:
        raise MetricError(f'need 0 < tau_true <= tau_false, got {tau_true}, {tau_false}')
    d = ftd_distances(truth, estimates, P0)
    t = d.shape[0]
    if d.shape[1] == 0:
        return TrackClasses(label=np.full(t, -1, np.int8), target=np.full(t, -1), distance=np.full(t, np.inf))
    target = d.argmin(axis=1)
    dist = d[np.arange(t), target]
    label = np.where(dist < tau_true, 1, np.where(dist > tau_false, -1, 0)).astype(np.int8)
    return TrackClasses(label=label, target=np.where(label == 1, target, -1), distance=dist)


@dataclass(frozen=True)
class ScanEvaluation:
    """One scan of one run: which targets have a CTT, its position error, and the track counts."""

    has_ctt: np.ndarray          # (G,) bool
    error: np.ndarray            # (G,) position error of the target's nearest CTT [m], NaN without one
    n_confirmed: int
    n_true: int
    n_false: int


def evaluate_scan(truth, tracks: np.ndarray, P0, tau_true: float = TAU_TRUE, tau_false: float = TAU_FALSE
                  ) -> ScanEvaluation:
    """Classify the confirmed tracks of a ``TRACK_DTYPE`` array against ``truth (G, 4)`` ``[x, y, vx, vy]``."""
    truth = _points(truth, 'truth')
    names = tracks.dtype.names or ()
    missing = [f for f in _STATE_FIELDS + ('confirmed',) if f not in names]
    if missing:
        raise MetricError(f'track records lack field(s) {missing}')
    conf = tracks[tracks['confirmed'] != 0]
    est = np.column_stack([conf[f].astype(float) for f in _STATE_FIELDS]) if len(conf) else np.zeros((0, 4))
    cls = classify_tracks(truth, est, P0, tau_true, tau_false)
    g = len(truth)
    has = np.zeros(g, bool)
    err = np.full(g, np.nan)
    for k in range(g):
        mine = np.flatnonzero(cls.target == k)
        if len(mine):
            e = np.hypot(est[mine, 0] - truth[k, 0], est[mine, 1] - truth[k, 1])
            has[k], err[k] = True, e.min()
    return ScanEvaluation(has_ctt=has, error=err, n_confirmed=len(conf), n_true=cls.n_true, n_false=cls.n_false)


def confirmed_true_track_rate(has_ctt) -> np.ndarray:
    """CTTR per scan: ``has_ctt (M runs, K scans[, G targets])`` bool -> ``(K,)`` fraction of runs (and targets)."""
    a = np.asarray(has_ctt, dtype=bool)
    if a.ndim not in (2, 3):
        raise MetricError(f'has_ctt must have shape (runs, scans) or (runs, scans, targets), got {a.shape}')
    return a.mean(axis=(0, 2) if a.ndim == 3 else 0)


def position_rmse(errors) -> np.ndarray:
    """Eq. (49) per scan: ``errors (M runs, K scans)`` position errors of CTTs [m], NaN where none.

    Returns ``(K,)``; a scan without any CTT gives NaN.
    """
    e = np.asarray(errors, dtype=float)
    if e.ndim != 2:
        raise MetricError(f'errors must have shape (runs, scans), got {e.shape}')
    have = ~np.isnan(e)
    n = have.sum(axis=0)
    sq = np.where(have, e * e, 0.0).sum(axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        return np.where(n > 0, np.sqrt(sq / np.maximum(n, 1)), np.nan)


def confirmed_false_track_rate(n_false) -> float:
    """Confirmed false tracks summed over scans and runs / (scans x runs); ``n_false (M, K)``."""
    a = np.asarray(n_false, dtype=float)
    if a.size == 0:
        raise MetricError('n_false is empty')
    return float(a.sum() / a.size)


def cft_scan_rate(n_false) -> float:
    """Rate of CFT as the ESC paper's Table 1 defines it: scans with at least one confirmed false
    track / (scans x runs); ``n_false (M, K)`` (a scan with two false tracks counts once)."""
    a = np.asarray(n_false)
    if a.size == 0:
        raise MetricError('n_false is empty')
    return float((a > 0).sum() / a.size)


def paired_difference(a: np.ndarray, b: np.ndarray) -> dict:
    """Mean of ``a - b`` over the runs where both are finite, with the half-width of its 95 %
    confidence interval (Student t) and the number of runs: with common random numbers the
    methods' run-to-run noise is shared, so this tells a real difference from Monte Carlo noise
    far better than two separate means do. ``ci95`` is None below two runs."""
    from scipy.stats import t as student_t
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    d = d[np.isfinite(d)]
    if d.size == 0:
        return {'difference': None, 'ci95': None, 'runs': 0}
    half = (float(student_t.ppf(0.975, d.size - 1) * d.std(ddof=1) / math.sqrt(d.size))
            if d.size >= 2 else None)
    return {'difference': float(d.mean()), 'ci95': half, 'runs': int(d.size)}


@dataclass(frozen=True)
class OspaResult:
    """OSPA distance and its parts: ``distance^p = localisation^p + cardinality^p``."""

    distance: float
    localisation: float
    cardinality: float


def _cutoff_costs(X: np.ndarray, Y: np.ndarray, c: float, p: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = np.sqrt(((X[:, None, :] - Y[None, :, :]) ** 2).sum(axis=-1))
    cost = np.minimum(d, c) ** p
    rows, cols = linear_sum_assignment(cost)
    return d, rows, cols


def _check(X, Y, c: float, p: float) -> tuple[np.ndarray, np.ndarray]:
    X, Y = _points(X, 'X'), _points(Y, 'Y')
    if len(X) and len(Y) and X.shape[1] != Y.shape[1]:
        raise MetricError(f'X has dimension {X.shape[1]}, Y {Y.shape[1]}')
    if not (c > 0 and math.isfinite(c)):
        raise MetricError(f'cut-off c = {c} must be finite and > 0')
    if not (p >= 1 and math.isfinite(p)):
        raise MetricError(f'order p = {p} must be finite and >= 1')
    return X, Y


def ospa(X, Y, c: float, p: float = 1.0) -> OspaResult:
    """OSPA distance of order ``p`` with cut-off ``c`` between point sets ``X (m, d)`` and ``Y (n, d)``.

    For ``m <= n``: ``(1/n (min_pi sum_i min(d(x_i, y_pi(i)), c)^p + c^p (n - m)))^(1/p)``
    (Schuhmacher, Vo & Vo 2008); 0 when both are empty, ``c`` when one is.
    """
    X, Y = _check(X, Y, c, p)
    m, n = len(X), len(Y)
    if m == 0 and n == 0:
        return OspaResult(0.0, 0.0, 0.0)
    big = max(m, n)
    if m == 0 or n == 0:
        return OspaResult(float(c), 0.0, float(c))
    d, rows, cols = _cutoff_costs(X, Y, c, p)
    loc = float(np.sum(np.minimum(d[rows, cols], c) ** p))
    card = float(c ** p * abs(n - m))
    return OspaResult(distance=((loc + card) / big) ** (1.0 / p), localisation=(loc / big) ** (1.0 / p),
                      cardinality=(card / big) ** (1.0 / p))


@dataclass(frozen=True)
class GospaResult:
    """GOSPA distance; for ``alpha = 2`` also its parts: ``distance^p = localisation^p + (missed + false) c^p / 2``."""

    distance: float
    localisation: float
    missed: int
    false: int


def gospa(X, Y, c: float, p: float = 2.0, alpha: float = 2.0) -> GospaResult:
    """GOSPA distance between the true set ``X (m, d)`` and the estimated set ``Y (n, d)``.

    For ``m <= n``: ``(min_pi sum_i min(d(x_i, y_pi(i)), c)^p + c^p / alpha (n - m))^(1/p)``, not
    normalised by the set size (Rahmathullah, Garcia-Fernandez & Svensson 2017). With
    ``alpha = 2`` this equals the assignment form
    ``(sum_assigned d^p + c^p / 2 (missed + false))^(1/p)``, where a pair at distance ``>= c``
    counts as one missed and one false target; ``missed`` and ``false`` are reported for that
    form (for other ``alpha`` they count the unassigned points).
    """
    X, Y = _check(X, Y, c, p)
    if not 0 < alpha <= 2:
        raise MetricError(f'alpha = {alpha} must be in (0, 2]')
    m, n = len(X), len(Y)
    if m == 0 or n == 0:
        return GospaResult(distance=(c ** p / alpha * (m + n)) ** (1.0 / p), localisation=0.0, missed=m, false=n)
    d, rows, cols = _cutoff_costs(X, Y, c, p)
    pair_d = d[rows, cols]
    total = float(np.sum(np.minimum(pair_d, c) ** p) + c ** p / alpha * abs(n - m))
    real = pair_d < c if alpha == 2 else np.ones(len(rows), bool)
    loc = float(np.sum(pair_d[real] ** p))
    n_real = int(np.count_nonzero(real))
    return GospaResult(distance=total ** (1.0 / p), localisation=loc ** (1.0 / p), missed=m - n_real, false=n - n_real)


def gospa_assignment(X, Y, c: float, p: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(rows of X, rows of Y)`` that :func:`gospa` (``alpha = 2``) assigns: its optimal
    assignment, keeping the pairs closer than ``c`` (the others count as missed and false)."""
    X, Y = _check(X, Y, c, p)
    if len(X) == 0 or len(Y) == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    d, rows, cols = _cutoff_costs(X, Y, c, p)
    real = d[rows, cols] < c
    return rows[real], cols[real]


def center_location_error(estimated, truth) -> np.ndarray | float:
    """FLS paper eq. (19): ``sqrt((x_p - x_g)^2 + (y_p - y_g)^2)`` between tracked centres
    ``(..., 2)`` and true centres ``(..., 2)`` (broadcast); a float for single points."""
    p = np.asarray(estimated, dtype=float)
    g = np.asarray(truth, dtype=float)
    if p.shape[-1:] != (2,) or g.shape[-1:] != (2,):
        raise MetricError(f'centres must have a last axis of 2 (x, y), got {p.shape} and {g.shape}')
    d = np.hypot(p[..., 0] - g[..., 0], p[..., 1] - g[..., 1])
    return float(d) if d.ndim == 0 else d

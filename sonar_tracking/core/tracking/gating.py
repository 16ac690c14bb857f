"""Validation gating and measurement likelihoods, eqs. (25)-(28), generic in measurement dimension.

The measurement is the position part of the state (``H = [I_d 0]``, eq. 27), each measurement
with its own covariance ``R_i``, so the innovation covariance ``S_i = H P H^T + R_i`` (eq. 26)
belongs to a (track, mode, measurement) triple.

Tracks and measurements are paired in two stages so the cost grows with the number of pairs
that can gate, not with tracks x measurements:

1. :func:`candidate_pairs` keeps the pairs whose measurement lies in the track's bounding box:
   the box of the gate ellipse ``nu^T S^-1 nu < gamma`` along axis j has half-width
   ``sqrt(gamma S_jj)``, bounded using the largest ``R_jj`` of the scan, and is united over the
   modes. Measurements are sorted along the first axis and each box found by binary search.
2. :func:`innovations` computes the exact statistics of the remaining pairs for every mode; a
   pair is validated for a mode when ``d^2 < gamma`` (eq. 25).

The gate size ``gamma`` and the gate probability ``P_G`` (eq. 28) are tied by the chi-square
distribution with d degrees of freedom (:func:`gate_threshold`, :func:`gate_probability`);
``P_G = 1`` means no gate (``gamma = inf``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammainc, gammaincinv

from .errors import TrackingInputError

__all__ = ['gate_threshold', 'gate_probability', 'candidate_pairs', 'candidate_counts', 'gate_boxes', 'Innovations',
           'innovations', 'gaussian_density']


def gate_threshold(p_gate: float, dim: int = 2) -> float:
    """Gate size ``gamma_G`` of eq. (25) that a true measurement passes with probability ``p_gate``.

    ``gamma = F^{-1}_{chi2, dim}(P_G)``; for ``dim = 2`` that is ``-2 ln(1 - P_G)``. ``P_G = 1``
    gives ``inf`` (no gate).
    """
    if not 0.0 < p_gate <= 1.0:
        raise TrackingInputError(f'gate probability {p_gate} must be in (0, 1]')
    if p_gate == 1.0:
        return math.inf
    if dim == 2:
        return -2.0 * math.log1p(-p_gate)
    return float(2.0 * gammaincinv(dim / 2.0, p_gate))


def gate_probability(gamma: float, dim: int = 2) -> float:
    """``P_G`` of eq. (28): probability that a chi-square variable with ``dim`` dof is below ``gamma``."""
    if gamma <= 0:
        raise TrackingInputError(f'gate size {gamma} must be > 0')
    if math.isinf(gamma):
        return 1.0
    return float(gammainc(dim / 2.0, gamma / 2.0))


def gate_boxes(centres: np.ndarray, hph_diag: np.ndarray, r_diag_max: np.ndarray, gamma: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned boxes ``(lo, hi)``, each ``(T, d)``, holding every mode's gate of every track.

    ``centres (d, M, T)`` predicted measurements, ``hph_diag (d, M, T)`` diagonals of
    ``H P H^T``, ``r_diag_max (d,)`` the largest measurement variance per axis in the scan.
    """
    if not math.isfinite(gamma):
        shape = (centres.shape[2], centres.shape[0])
        return np.full(shape, -np.inf), np.full(shape, np.inf)
    half = np.sqrt(gamma * (hph_diag + np.asarray(r_diag_max)[:, None, None]))
    return np.minimum.reduce(centres - half, axis=1).T, np.maximum.reduce(centres + half, axis=1).T


# Up to this many track-measurement combinations, testing all of them beats the strip search.
_BRUTE_FORCE_PAIRS = 20000


class BoxSearch:
    """The measurements ``z (N, d)`` inside each track's box ``lo, hi (T, d)``, found once and asked
    for twice (a pair budget counts them before the update gates them).

    Measurements are binned into strips along the first axis (as wide as the mean box, and never
    more strips than measurements) and sorted by (strip, second coordinate); each track looks up, in
    every strip its box overlaps, the measurements within its second-axis range by binary search.
    Only those are checked against the box, so the work follows the pairs that can gate rather than
    tracks x measurements. Small problems test every box at once.
    """

    def __init__(self, lo: np.ndarray, hi: np.ndarray, z: np.ndarray) -> None:
        self.lo, self.hi, self.z = lo, hi, z
        n_tracks, n_meas = lo.shape[0], z.shape[0]
        finite = np.count_nonzero(np.isfinite(lo)) + np.count_nonzero(np.isfinite(hi)) == lo.size + hi.size
        self.kind = ('empty' if n_tracks == 0 or n_meas == 0 else
                     'all' if not finite else   # no gate: every pair
                     'dense' if n_tracks * n_meas <= _BRUTE_FORCE_PAIRS else 'strips')
        self._strips: tuple | None = None

    def _search(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if self._strips is None:
            self._strips = _strip_search(self.lo, self.hi, self.z)
        return self._strips

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Pairs ``(track, measurement)`` whose measurement lies inside the track's box, as index
        arrays sorted by track (the order the IPDA reductions rely on)."""
        lo, hi, z = self.lo, self.hi, self.z
        n_tracks, n_meas = lo.shape[0], z.shape[0]
        if self.kind == 'empty':
            empty = np.zeros(0, dtype=np.intp)
            return empty, empty
        if self.kind == 'all':
            return np.repeat(np.arange(n_tracks), n_meas), np.tile(np.arange(n_meas), n_tracks)
        if self.kind == 'dense':
            track, meas = _inside(lo, hi, z).nonzero()
            return track, meas
        order, tr, first, count = self._search()
        track = np.repeat(tr, count)
        start = np.cumsum(count) - count
        meas = order[np.arange(len(track)) - np.repeat(start - first, count)]
        keep = (z[meas, 0] >= lo[track, 0]) & (z[meas, 0] <= hi[track, 0])
        for j in range(1, z.shape[1]):
            zj = z[meas, j]
            keep &= (zj >= lo[track, j]) & (zj <= hi[track, j])
        return track[keep], meas[keep]

    def counts(self) -> np.ndarray:
        """``(T,)`` upper bound on the pairs :meth:`pairs` returns per track, without building them
        (the measurements of the strip search, before the exact box test)."""
        n_tracks, n_meas = self.lo.shape[0], self.z.shape[0]
        if self.kind == 'empty':
            return np.zeros(n_tracks, dtype=np.intp)
        if self.kind == 'all':
            return np.full(n_tracks, n_meas, dtype=np.intp)
        if self.kind == 'dense':
            return np.count_nonzero(_inside(self.lo, self.hi, self.z), axis=1)
        _, tr, _, count = self._search()
        return np.bincount(tr, weights=count, minlength=n_tracks).astype(np.intp)


def candidate_pairs(lo: np.ndarray, hi: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(track, measurement)`` whose measurement lies inside the track's box (:class:`BoxSearch`)."""
    return BoxSearch(lo, hi, z).pairs()


def candidate_counts(lo: np.ndarray, hi: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``(T,)`` upper bound on the pairs :func:`candidate_pairs` returns per track (:class:`BoxSearch`)."""
    return BoxSearch(lo, hi, z).counts()


def _inside(lo: np.ndarray, hi: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``(T, N)`` bool: measurement n lies in box t."""
    inside = (z[:, 0] >= lo[:, 0, None]) & (z[:, 0] <= hi[:, 0, None])
    for j in range(1, z.shape[1]):
        inside &= (z[:, j] >= lo[:, j, None]) & (z[:, j] <= hi[:, j, None])
    return inside


def _strip_search(lo: np.ndarray, hi: np.ndarray, z: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The strip search of :func:`candidate_pairs`: measurement ``order`` and, per (track, strip)
    the box overlaps, the track ``tr``, the ``first`` position in ``order`` and the ``count``."""
    n_tracks, n_meas = lo.shape[0], z.shape[0]
    zx = z[:, 0]
    zy = z[:, 1] if z.shape[1] > 1 else np.zeros(n_meas)
    x0, span_x = zx.min(), zx.max() - zx.min()
    width = max(float(np.mean(hi[:, 0] - lo[:, 0])), span_x / n_meas, 1e-9)
    n_strips = int(span_x // width) + 1
    y0 = zy.min()
    span_y = zy.max() - y0 + 1.0
    # The same expression bins points and box edges, so a point on an edge lands in the edge's strip.
    strip = np.minimum(np.floor((zx - x0) / width).astype(np.intp), n_strips - 1)
    key = strip * span_y + (zy - y0)
    order = np.argsort(key, kind='stable')
    keys = key[order]
    s_lo = np.clip(np.floor((lo[:, 0] - x0) / width), 0, n_strips - 1).astype(np.intp)
    s_hi = np.clip(np.floor((hi[:, 0] - x0) / width), -1, n_strips - 1).astype(np.intp)
    ns = np.maximum(s_hi - s_lo + 1, 0)
    tr = np.repeat(np.arange(n_tracks), ns)
    st = np.arange(len(tr)) - np.repeat(np.cumsum(ns) - ns - s_lo, ns)
    if z.shape[1] > 1:
        ylo = np.clip(lo[tr, 1] - y0, 0.0, span_y)
        yhi = np.clip(hi[tr, 1] - y0, -0.5, span_y - 0.5)
    else:
        ylo, yhi = np.zeros(len(tr)), np.zeros(len(tr))
    first = np.searchsorted(keys, st * span_y + ylo, side='left')
    count = np.maximum(np.searchsorted(keys, st * span_y + yhi, side='right') - first, 0)
    return order, tr, first, count


@dataclass(frozen=True)
class Innovations:
    """Per (mode, pair) innovation statistics, component-major with pairs last.

    ``nu (d, M, P)`` innovation ``z - H x_pred``; ``s_inv (d, d, M, P)`` inverse of eq. (26);
    ``w (d, M, P) = S^-1 nu``; ``d2 (M, P)`` the gate statistic of eq. (25); ``det (M, P)``
    ``det S``.
    """

    nu: np.ndarray
    s_inv: np.ndarray
    w: np.ndarray
    d2: np.ndarray
    det: np.ndarray
    #: ``(d + d^2 + d + 2, M, P)`` rows holding all five above (views of it), or None.
    buffer: np.ndarray | None = field(default=None, repr=False, compare=False)

    @staticmethod
    def from_buffer(buffer: np.ndarray, d: int) -> 'Innovations':
        """The statistics as views of one array whose rows are ``nu, s_inv, w, d2, det`` (see ``buffer``)."""
        e = 2 * d + d * d
        return Innovations(nu=buffer[:d], s_inv=buffer[d:d + d * d].reshape((d, d) + buffer.shape[1:]),
                           w=buffer[d + d * d:e], d2=buffer[e], det=buffer[e + 1], buffer=buffer)

    def density(self) -> np.ndarray:
        """``N(z; H x_pred, S)`` for every mode and pair (the numerator of eq. 28)."""
        return gaussian_density(self.d2, self.det, self.nu.shape[0])

    def select(self, keep: np.ndarray) -> 'Innovations':
        """The statistics of the pairs ``keep`` (indices, or a ``(P,)`` bool mask)."""
        idx = keep.nonzero()[0] if keep.dtype == bool else keep
        if self.buffer is not None:            # one gather for all five
            return Innovations.from_buffer(self.buffer.take(idx, axis=-1), self.nu.shape[0])
        return Innovations(nu=self.nu.take(idx, axis=-1), s_inv=self.s_inv.take(idx, axis=-1),
                           w=self.w.take(idx, axis=-1), d2=self.d2.take(idx, axis=-1),
                           det=self.det.take(idx, axis=-1))


def gaussian_density(d2: np.ndarray, det: np.ndarray, dim: int) -> np.ndarray:
    """Normal density from its Mahalanobis distance ``d2`` and covariance determinant ``det``."""
    return np.exp(-0.5 * d2) / np.sqrt((2.0 * math.pi) ** dim * det)


def innovations(z: np.ndarray, R: np.ndarray, z_pred: np.ndarray, hph: np.ndarray) -> Innovations:
    """Innovation statistics for P pairs and M modes (component-major, pairs last).

    Parameters
    ----------
    z : ``(d, P)`` measurement of each pair.
    R : ``(d, d, P)`` its covariance.
    z_pred : ``(d, M, P)`` predicted measurement ``H x_pred`` of the pair's track, per mode.
    hph : ``(d, d, M, P)`` ``H P_pred H^T`` of the pair's track, per mode.

    ``S = hph + R`` (eq. 26). For ``d = 2`` the inverse and determinant are closed-form; other
    dimensions use ``numpy.linalg``. Raises TrackingInputError for non-matching shapes.
    """
    d = z.shape[0]
    if z.ndim != 2 or z_pred.shape[0] != d or z_pred.shape[-1] != z.shape[1] or R.shape[:2] != (d, d):
        raise TrackingInputError(f'innovations: z {z.shape}, R {R.shape} and z_pred {z_pred.shape} do not match')
    if d == 2:
        # All five statistics written into one array (rows nu, s_inv, w, d2, det): selecting
        # pairs later is one gather.
        out = Innovations.from_buffer(np.empty((10,) + z_pred.shape[1:]), 2)
        nu, s_inv, w, d2, det = out.nu, out.s_inv, out.w, out.d2, out.det
        np.subtract(z[:, None, :], z_pred, out=nu)
        a = hph[0, 0] + R[0, 0]
        b = hph[0, 1] + hph[1, 0]
        b += R[0, 1]
        b += R[1, 0]
        b *= 0.5
        c = hph[1, 1] + R[1, 1]
        np.multiply(a, c, out=det)
        det -= b * b
        np.divide(c, det, out=s_inv[0, 0])
        np.divide(a, det, out=s_inv[1, 1])
        np.divide(b, det, out=s_inv[0, 1])
        np.negative(s_inv[0, 1], out=s_inv[0, 1])
        s_inv[1, 0] = s_inv[0, 1]
        np.multiply(s_inv[0, 0], nu[0], out=w[0])
        w[0] += s_inv[0, 1] * nu[1]
        np.multiply(s_inv[1, 1], nu[1], out=w[1])
        w[1] += s_inv[0, 1] * nu[0]
        np.multiply(nu[0], w[0], out=d2)
        d2 += nu[1] * w[1]
        return out
    nu = z[:, None, :] - z_pred
    S = hph + R[:, :, None, :]
    S = np.moveaxis(0.5 * (S + S.swapaxes(0, 1)), (0, 1), (-2, -1))     # (M, P, d, d)
    det = np.linalg.det(S)
    s_inv = np.moveaxis(np.linalg.inv(S), (-2, -1), (0, 1))
    w = np.einsum('ijmp,jmp->imp', s_inv, nu)
    d2 = np.sum(nu * w, axis=0)
    return Innovations(nu=nu, s_inv=s_inv, w=w, d2=d2, det=det)

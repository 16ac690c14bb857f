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

from sonar_tracking.core.jit import kernel
from sonar_tracking.core.tracking.errors import TrackingInputError

__all__ = ['gate_threshold', 'gate_probability', 'candidate_pairs', 'candidate_counts', 'gate_boxes', 'Innovations',
           'innovations', 'gaussian_density', 'gate_pairs']


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
    d, _, n_tracks = centres.shape
    lo, hi = np.empty((n_tracks, d)), np.empty((n_tracks, d))
    _gate_boxes(centres, hph_diag, np.asarray(r_diag_max, dtype=float), float(gamma), lo, hi)
    return lo, hi


@kernel
def _gate_boxes(centres, hph_diag, r_diag_max, gamma, lo, hi):
    """:func:`gate_boxes` into ``lo``, ``hi`` (compiled): half-widths ``sqrt(gamma (H P H^T_jj + max R_jj))``."""
    d, n_modes, n_tracks = centres.shape
    for t in range(n_tracks):
        for j in range(d):
            low, high = np.inf, -np.inf
            for m in range(n_modes):
                half = np.sqrt(gamma * (hph_diag[j, m, t] + r_diag_max[j]))
                a, b = centres[j, m, t] - half, centres[j, m, t] + half
                # NaN wins, as in np.minimum / np.maximum (a NaN box means no gate: every pair).
                low = a if (a < low or np.isnan(a)) and not np.isnan(low) else low
                high = b if (b > high or np.isnan(b)) and not np.isnan(high) else high
            lo[t, j], hi[t, j] = low, high


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
        self._counts: np.ndarray | None = None
        self._ranges: np.ndarray | None = None

    def _search(self) -> tuple:
        if self._strips is None:
            self._strips = _strip_order(self.z, self.lo, self.hi)
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
            track, meas = np.empty(n_tracks * n_meas, dtype=np.intp), np.empty(n_tracks * n_meas, dtype=np.intp)
            k = _inside_pairs(lo, hi, z, track, meas)
            return track[:k], meas[:k]
        counts = self.counts()
        track, meas = np.empty(int(counts.sum()), dtype=np.intp), np.empty(int(counts.sum()), dtype=np.intp)
        k = _strip_pairs(lo, hi, z, *self._search(), self._ranges, track, meas)
        return track[:k], meas[:k]

    def counts(self) -> np.ndarray:
        """``(T,)`` upper bound on the pairs :meth:`pairs` returns per track, without building them
        (the measurements of the strip search, before the exact box test)."""
        n_tracks, n_meas = self.lo.shape[0], self.z.shape[0]
        if self.kind == 'empty':
            return np.zeros(n_tracks, dtype=np.intp)
        if self.kind == 'all':
            return np.full(n_tracks, n_meas, dtype=np.intp)
        if self.kind == 'dense':
            counts = np.empty(n_tracks, dtype=np.intp)
            _inside_counts(self.lo, self.hi, self.z, counts)
            return counts
        if self._counts is None:
            self._counts = np.empty(n_tracks, dtype=np.intp)
            self._ranges = np.empty((n_tracks, _KEPT_RANGES, 2), dtype=np.intp)
            _strip_counts(self.lo, self.hi, *self._search(), self._counts, self._ranges)
        return self._counts


def candidate_pairs(lo: np.ndarray, hi: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(track, measurement)`` whose measurement lies inside the track's box (:class:`BoxSearch`)."""
    return BoxSearch(lo, hi, z).pairs()


def candidate_counts(lo: np.ndarray, hi: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``(T,)`` upper bound on the pairs :func:`candidate_pairs` returns per track (:class:`BoxSearch`)."""
    return BoxSearch(lo, hi, z).counts()


@kernel
def _inside_counts(lo, hi, z, counts):
    """Per track, the measurements inside its box, into ``counts`` (compiled)."""
    for t in range(lo.shape[0]):
        n = 0
        for i in range(z.shape[0]):
            n += _in_box(z, i, lo, hi, t)
        counts[t] = n


@kernel
def _inside_pairs(lo, hi, z, track, meas):
    """Every (track, measurement) with the measurement inside the track's box, by track then
    measurement, into ``track``, ``meas``; returns their number (compiled)."""
    k = 0
    for t in range(lo.shape[0]):
        for i in range(z.shape[0]):
            if _in_box(z, i, lo, hi, t):
                track[k] = t
                meas[k] = i
                k += 1
    return k


@kernel
def _in_box(z, i, lo, hi, t):
    """Measurement ``i`` lies in track ``t``'s box, edges included (compiled scalar)."""
    for j in range(z.shape[1]):  # noqa: SIM110 - a compiled loop; numba has no all() of a generator
        if not (z[i, j] >= lo[t, j] and z[i, j] <= hi[t, j]):
            return False
    return True


def _strip_order(z: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple:
    """The measurements of the strip search sorted by (strip, second coordinate): ``order``, their
    sort ``keys``, the start in ``keys`` of each of ``2 N`` buckets of equal key width from ``k0`` on
    (``table``, ``k0``, ``bucket``) and the strip geometry ``x0, width, n_strips, y0, span_y``."""
    n_meas = z.shape[0]
    zx = z[:, 0]
    zy = z[:, 1] if z.shape[1] > 1 else np.zeros(n_meas)
    x0, span_x = zx.min(), zx.max() - zx.min()
    width = max(float(np.mean(hi[:, 0] - lo[:, 0])), span_x / n_meas, 1e-9)
    n_strips = int(span_x // width) + 1
    y0 = zy.min()
    span_y = zy.max() - y0 + 1.0
    key = np.empty(n_meas)
    _strip_keys(z, float(x0), float(width), n_strips, float(y0), float(span_y), key)
    order = np.argsort(key, kind='stable')
    keys = key[order]
    # Buckets of equal key width: where each bucket's keys start, so a search starts near its answer.
    bucket = (keys[-1] - keys[0]) / (2 * n_meas) + 1e-300
    table = np.empty(2 * n_meas + 1, dtype=np.intp)
    _bucket_table(keys, bucket, table)
    return (order, keys, table, float(keys[0]), float(bucket), float(x0), float(width), n_strips, float(y0),
            float(span_y))


@kernel
def _strip_keys(z, x0, width, n_strips, y0, span_y, key):
    """Sort key of each measurement: its strip times ``span_y`` plus its second coordinate from
    ``y0`` (compiled)."""
    for i in range(z.shape[0]):
        # The same expression bins points and box edges, so a point on an edge lands in the edge's strip.
        st = min(int(np.floor((z[i, 0] - x0) / width)), n_strips - 1)
        key[i] = st * span_y + ((z[i, 1] - y0) if z.shape[1] > 1 else 0.0)


@kernel
def _bucket_table(keys, bucket, table):
    """``table[b]``: the first of the sorted ``keys`` at or above ``keys[0] + b bucket``, i.e.
    ``np.searchsorted(keys, keys[0] + bucket * np.arange(B), 'left')``; the last entry is ``len(keys)``
    (compiled)."""
    j, n = 0, keys.size
    for b in range(table.size - 1):
        edge = keys[0] + bucket * b
        while j < n and keys[j] < edge:
            j += 1
        table[b] = j
    table[table.size - 1] = n


@kernel
def _strip_range(keys, table, k0, bucket, st, span_y, ylo, yhi):
    """Positions ``[first, end)`` in ``keys`` of the measurements of strip ``st`` whose second
    coordinate (from its minimum) lies in ``[ylo, yhi]`` (compiled)."""
    first = _first_at(keys, table, k0, bucket, st * span_y + ylo)
    # The end: a walk over the few candidates a box usually holds, a bisection past 16 of them.
    end, top, n = first, st * span_y + yhi, keys.size
    stop = min(first + 16, n)
    while end < stop and keys[end] <= top:
        end += 1
    if end == stop and end < n:
        hi = n
        while end < hi:
            mid = (end + hi) // 2
            if keys[mid] <= top:
                end = mid + 1
            else:
                hi = mid
    return first, end


@kernel
def _first_at(keys, table, k0, bucket, x):
    """``np.searchsorted(keys, x, 'left')``, bisecting only ``x``'s own bucket and one either side
    (which absorbs the rounding of the bucket arithmetic; compiled)."""
    n_buckets = table.size - 1
    b = (x - k0) / bucket
    if not b >= 0.0:          # below the first key, or NaN
        b = 0.0
    b = min(b, n_buckets - 1.0)
    lo = table[max(int(b) - 1, 0)]
    hi = table[min(int(b) + 2, n_buckets)]
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def _strips_of(lo, hi, t, x0, width, n_strips):
    """The strips ``[s_lo, s_hi]`` track ``t``'s box overlaps along the first axis (compiled)."""
    s_lo = int(min(max(np.floor((lo[t, 0] - x0) / width), 0.0), n_strips - 1.0))
    s_hi = int(min(max(np.floor((hi[t, 0] - x0) / width), -1.0), n_strips - 1.0))
    return s_lo, s_hi


@kernel
def _y_range(lo, hi, t, y0, span_y):
    """Track ``t``'s second-axis range from the measurements' minimum, clipped to the keys' span
    (``0, 0`` for one-dimensional measurements; compiled)."""
    if lo.shape[1] > 1:
        return min(max(lo[t, 1] - y0, 0.0), span_y), min(max(hi[t, 1] - y0, -0.5), span_y - 0.5)
    return 0.0, 0.0


#: Strip ranges kept per track between counting and listing the pairs (a box over more strips
#: searches them again): bounds the memory at this many per track.
_KEPT_RANGES = 4


@kernel
def _strip_counts(lo, hi, order, keys, table, k0, bucket, x0, width, n_strips, y0, span_y, counts, ranges):
    """Per track, the measurements of the strip search (before the exact box test) into ``counts``,
    and the positions ``[first, end)`` of its first ``_KEPT_RANGES`` strips into ``ranges (T, K, 2)``."""
    for t in range(lo.shape[0]):
        s_lo, s_hi = _strips_of(lo, hi, t, x0, width, n_strips)
        ylo, yhi = _y_range(lo, hi, t, y0, span_y)
        n = 0
        for st in range(s_lo, s_hi + 1):
            first, end = _strip_range(keys, table, k0, bucket, st, span_y, ylo, yhi)
            if st - s_lo < ranges.shape[1]:
                ranges[t, st - s_lo, 0], ranges[t, st - s_lo, 1] = first, end
            n += end - first
        counts[t] = n


@kernel
def _strip_pairs(lo, hi, z, order, keys, table, k0, bucket, x0, width, n_strips, y0, span_y, ranges, track, meas):
    """The strip search's pairs inside their track's box, by track, then strip, then key, into
    ``track``, ``meas`` (strip ranges from :func:`_strip_counts`); returns their number."""
    k = 0
    for t in range(lo.shape[0]):
        s_lo, s_hi = _strips_of(lo, hi, t, x0, width, n_strips)
        ylo, yhi = _y_range(lo, hi, t, y0, span_y)
        for st in range(s_lo, s_hi + 1):
            if st - s_lo < ranges.shape[1]:
                first, end = ranges[t, st - s_lo, 0], ranges[t, st - s_lo, 1]
            else:
                first, end = _strip_range(keys, table, k0, bucket, st, span_y, ylo, yhi)
            for p in range(first, end):
                i = order[p]
                if _in_box(z, i, lo, hi, t):
                    track[k] = t
                    meas[k] = i
                    k += 1
    return k


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
    def from_buffer(buffer: np.ndarray, d: int) -> Innovations:
        """The statistics as views of one array whose rows are ``nu, s_inv, w, d2, det`` (see ``buffer``)."""
        e = 2 * d + d * d
        return Innovations(nu=buffer[:d], s_inv=buffer[d:d + d * d].reshape((d, d) + buffer.shape[1:]),
                           w=buffer[d + d * d:e], d2=buffer[e], det=buffer[e + 1], buffer=buffer)

    def density(self) -> np.ndarray:
        """``N(z; H x_pred, S)`` for every mode and pair (the numerator of eq. 28)."""
        return gaussian_density(self.d2, self.det, self.nu.shape[0])

    def select(self, keep: np.ndarray) -> Innovations:
        """The statistics of the pairs ``keep`` (indices, or a ``(P,)`` bool mask)."""
        idx = keep.nonzero()[0] if keep.dtype == bool else keep
        if self.buffer is not None:            # one gather for all five
            return Innovations.from_buffer(self.buffer.take(idx, axis=-1), self.nu.shape[0])
        return Innovations(nu=self.nu.take(idx, axis=-1), s_inv=self.s_inv.take(idx, axis=-1),
                           w=self.w.take(idx, axis=-1), d2=self.d2.take(idx, axis=-1),
                           det=self.det.take(idx, axis=-1))


def gaussian_density(d2: np.ndarray, det: np.ndarray, dim: int) -> np.ndarray:
    """Normal density from its Mahalanobis distance ``d2`` and covariance determinant ``det``."""
    d2, det = np.broadcast_arrays(np.asarray(d2, dtype=float), np.asarray(det, dtype=float))
    out = np.empty(d2.shape)
    _densities(d2.ravel(), det.ravel(), (2.0 * math.pi) ** dim, out.reshape(-1))
    return out


@kernel
def normal_density(d2, det, norm):
    """``exp(-d2 / 2) / sqrt(norm det)``, ``norm = (2 pi)^d``: the normal density (compiled scalar)."""
    return np.exp(-0.5 * d2) / np.sqrt(norm * det)


@kernel
def _densities(d2, det, norm, out):
    for i in range(len(d2)):
        out[i] = normal_density(d2[i], det[i], norm)


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
        # All five statistics in one array (rows nu, s_inv, w, d2, det): selecting pairs is one gather.
        buffer = np.empty((10,) + z_pred.shape[1:])
        _innovations_2d(z, R, z_pred, hph, buffer)
        return Innovations.from_buffer(buffer, 2)
    nu = z[:, None, :] - z_pred
    S = hph + R[:, :, None, :]
    S = np.moveaxis(0.5 * (S + S.swapaxes(0, 1)), (0, 1), (-2, -1))     # (M, P, d, d)
    det = np.linalg.det(S)
    s_inv = np.moveaxis(np.linalg.inv(S), (-2, -1), (0, 1))
    w = np.einsum('ijmp,jmp->imp', s_inv, nu)
    d2 = np.sum(nu * w, axis=0)
    return Innovations(nu=nu, s_inv=s_inv, w=w, d2=d2, det=det)


def gate_pairs(track_side: np.ndarray, meas_side: np.ndarray, pt: np.ndarray, pm: np.ndarray, gamma: float
               ) -> tuple[np.ndarray, np.ndarray, Innovations, np.ndarray]:
    """The candidate pairs ``(pt, pm)`` validated for at least one mode (eq. 25), with their statistics.

    ``track_side (d + d^2, M, T)`` holds ``H x_pred`` and ``H P_pred H^T`` (row-major) of each track
    and mode, ``meas_side (d + d^2, N)`` ``z`` and ``R`` of each measurement. Returns the kept
    ``pt, pm`` (order kept), their :func:`innovations` and ``in_gate (M, P)``, ``d2 < gamma``.
    ``pt`` and ``pm`` may be overwritten.
    """
    d = int(round((math.sqrt(4 * meas_side.shape[0] + 1) - 1) / 2))      # rows d + d^2
    if d == 2 and len(pt):
        buffer = np.empty((10, track_side.shape[1], len(pt)))
        in_gate = np.empty((track_side.shape[1], len(pt)), dtype=bool)
        kept = _gate_pairs_2d(track_side, meas_side, pt, pm, gamma, buffer, in_gate)
        if kept == len(pt):
            return pt, pm, Innovations.from_buffer(buffer, 2), in_gate
        # The kernel moved the kept pairs to the front of every array.
        return (pt[:kept], pm[:kept], Innovations.from_buffer(np.ascontiguousarray(buffer[..., :kept]), 2),
                np.ascontiguousarray(in_gate[:, :kept]))
    tg = np.take(track_side, pt, axis=-1)
    mg = np.take(meas_side, pm, axis=-1)
    innov = innovations(mg[:d], mg[d:].reshape(d, d, -1), tg[:d], tg[d:].reshape(d, d, *tg.shape[1:]))
    in_gate = innov.d2 < gamma
    valid = in_gate.any(axis=0)
    if not valid.all():
        keep = np.flatnonzero(valid)
        pt, pm, in_gate, innov = pt[keep], pm[keep], in_gate[:, keep], innov.select(keep)
    return pt, pm, innov, in_gate


@kernel
def _innovation_2d(out, m, p, z0, z1, r00, r01, r10, r11, zp0, zp1, h00, h01, h10, h11):
    """Eqs. (25)-(26) for one (mode, pair), d = 2, into ``out[:, m, p]`` (rows nu, s_inv, w, d2, det).

    ``S`` is symmetrised (the mean of its off-diagonal entries), inverted in closed form."""
    nu0 = z0 - zp0
    nu1 = z1 - zp1
    a = h00 + r00
    b = h01 + h10
    b += r01
    b += r10
    b *= 0.5
    c = h11 + r11
    det = a * c
    det -= b * b
    s00 = c / det
    s11 = a / det
    s01 = -(b / det)
    w0 = s00 * nu0
    w0 += s01 * nu1
    w1 = s11 * nu1
    w1 += s01 * nu0
    d2 = nu0 * w0
    d2 += nu1 * w1
    out[0, m, p] = nu0
    out[1, m, p] = nu1
    out[2, m, p] = s00
    out[3, m, p] = s01
    out[4, m, p] = s01
    out[5, m, p] = s11
    out[6, m, p] = w0
    out[7, m, p] = w1
    out[8, m, p] = d2
    out[9, m, p] = det


@kernel
def _innovations_2d(z, R, z_pred, hph, out):
    """:func:`innovations` for d = 2 into ``out (10, M, P)`` (compiled)."""
    n_modes, n_pairs = z_pred.shape[1], z_pred.shape[2]
    for p in range(n_pairs):
        for m in range(n_modes):
            _innovation_2d(out, m, p, z[0, p], z[1, p], R[0, 0, p], R[0, 1, p], R[1, 0, p], R[1, 1, p],
                           z_pred[0, m, p], z_pred[1, m, p], hph[0, 0, m, p], hph[0, 1, m, p], hph[1, 0, m, p],
                           hph[1, 1, m, p])


@kernel
def _gate_pairs_2d(ts, ms, pt, pm, gamma, out, in_gate):
    """:func:`gate_pairs` for d = 2 (compiled): statistics of every candidate pair, then the pairs
    some mode validates moved to the front (``pt``, ``pm``, ``out``, ``in_gate`` in place); returns
    how many were kept."""
    n_modes = ts.shape[1]
    kept = 0
    for p in range(len(pt)):
        t, i = pt[p], pm[p]
        valid = False
        for m in range(n_modes):
            _innovation_2d(out, m, kept, ms[0, i], ms[1, i], ms[2, i], ms[3, i], ms[4, i], ms[5, i],
                           ts[0, m, t], ts[1, m, t], ts[2, m, t], ts[3, m, t], ts[4, m, t], ts[5, m, t])
            g = out[8, m, kept] < gamma
            in_gate[m, kept] = g
            valid = valid or g
        if valid:
            pt[kept] = t
            pm[kept] = i
            kept += 1
    return kept

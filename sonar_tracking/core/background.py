"""The local-background rule: the clutter level a cell's echo is measured against.

Both front ends judge an echo by the clutter around it: the FLS filter divides every range bin by
the background level at that range before it filters and segments (:mod:`.fls.filters`), and
CFAR detection (:mod:`.detection.cfar`) compares each cell with the level of training cells
around it. This module is the one place that says how that level is estimated:

1. **What counts as background.** Only measured cells: an exact zero is no data (below the
   sensor's gain floor, blanked, or beyond its range; imaging sonars report 45-73 % of a range bin
   as 0 in open water), and so is a non-finite value (:func:`measured`). Cells outside the sector
   are no data too. Estimates use the measured cells alone and report how many they had, so a
   caller can correct for a short sample instead of mistaking zeros for quiet water. Where the
   zeros are the cells below a known floor ``f`` (8-bit counts: half a count above 0, see
   :func:`sonar_tracking.core.intensity.zero_floor`), the window estimates take the measured cells'
   excess over ``f``: an exponential law forgets the floor (the excess of a cell above ``f`` is
   exponential with the same mean), so the level comes out unbiased from the measured cells alone,
   where their plain mean would be too high by up to ``f``.
2. **Speckle model.** Clutter intensity is fully developed speckle: exponential with the local mean
   as its only parameter (compound laws such as K are exponential given their texture). The level
   is that mean, estimated from the training cells by their mean (``ca``), the greater of the means
   of the nearer and the farther half (``go``, robust at clutter edges), or an order statistic
   (``os``, robust to other targets among the training cells). An order statistic is scaled to the
   mean by its expectation for unit exponentials (:func:`exponential_order_mean`; ln 2 for the
   median of many cells).
3. **Where the training cells are.** :class:`Window`: a guard region around the cell under test
   (its own echo, smeared by the beam pattern and the pulse, stays out) and training cells around
   it out to a reach in bins and beams, taken every ``stride`` bins and beams. Imaging sonars form
   more beams than their beam width resolves (an Oculus M750d: 512 beams over 130 deg with a beam
   about 1 deg wide), so neighbouring cells are correlated; a stride of about one resolution cell
   makes the training cells nearly independent, which the false-alarm arithmetic of CFAR assumes.

Two layouts use these rules: :func:`range_profile` (one level per range bin: the median of the
bin's measured beams, smoothed along range; the FLS filter's normalisation) and
:func:`window_sums` / :func:`window_order` (a level per cell from its own window; CFAR).

The window sums are float32 sums of a few hundred cells, so their last bits depend on the order of
the additions. :meth:`Window.correlate` takes OpenCV's separable filter; :func:`window_sums` of the
whole window (cell-averaging CFAR, an imaging frame at frame rate) takes a compiled kernel that adds
in the same order (:func:`_ca_sums`), bit for bit, in one pass over the frame without the
intermediate images.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numba import uintp
from scipy.ndimage import median_filter, rank_filter

from sonar_tracking.core.jit import kernel

__all__ = ['measured', 'exponential_order_mean', 'range_profile', 'Window', 'WindowSums', 'window_sums',
           'window_order', 'LN2']

#: Median of a unit-mean exponential: the median of many speckle cells is ln 2 times their mean.
LN2 = math.log(2.0)


def measured(values: np.ndarray) -> np.ndarray:
    """Cells that hold a measurement: finite and not exactly zero (rule 1)."""
    v = np.asarray(values)
    return np.isfinite(v) & (v != 0)


def exponential_order_mean(n: int, k: int) -> float:
    """Expectation of the ``k``-th smallest of ``n`` unit-mean exponentials: ``sum_{i=n-k+1}^{n} 1/i``."""
    if not 1 <= k <= n:
        raise ValueError(f'order statistic k = {k} must lie in 1..{n}')
    return float(np.sum(1.0 / np.arange(n - k + 1, n + 1)))


def range_profile(raw: np.ndarray, background_bins: int) -> np.ndarray:
    """Mean background intensity per range bin of beams ``raw`` (bins x beams): the median of each
    bin's measured cells, smoothed along range by a median over ``background_bins`` bins, divided
    by :data:`LN2` (rule 2). Always > 0.

    A bin with fewer than ``max(3, 10 %)`` of its beams measured takes the level of the nearest bins
    that have enough (interpolated between them); if none has, the median of all measured cells
    (ln 2 if there are none, a level of 1). Levels are floored at the smallest positive level, so no
    bin divides by zero. Without unmeasured cells this is the plain per-bin median.
    """
    v = np.asarray(raw)
    data = measured(v) & (v > 0)
    if data.all():
        prof = np.median(v, axis=1)
    else:
        prof = np.full(v.shape[0], np.nan, dtype=np.result_type(v.dtype, np.float32))
        enough = data.sum(axis=1) >= max(3, math.ceil(0.1 * v.shape[1]))
        if enough.any():
            prof[enough] = np.nanmedian(np.where(data[enough], v[enough], np.nan), axis=1)
            idx = np.arange(v.shape[0])
            prof[~enough] = np.interp(idx[~enough], idx[enough], prof[enough])
        else:
            prof[:] = np.median(v[data]) if data.any() else LN2
    if background_bins > 1 and prof.size > 1:
        prof = median_filter(prof, size=min(background_bins, 2 * prof.size - 1), mode='nearest')
    level = prof / LN2
    positive = level[level > 0]
    floor = positive.min() if positive.size else 1.0
    return np.maximum(level, floor)


@dataclass(frozen=True)
class Window:
    """Training cells around a cell under test (rule 3), offsets in image cells.

    Training offsets ``(i, j)`` (bins, beams) are the multiples of ``(stride_bins, stride_beams)``
    with ``|i| <= reach_bins`` and ``|j| <= reach_beams``, except those with ``|i| <= guard_bins``
    and ``|j| <= guard_beams``. The *nearer* half is ``i < 0`` together with ``i = 0, j < 0``; the
    farther half is its mirror image, so both hold :attr:`size` / 2 cells.
    """

    guard_bins: int = 2
    guard_beams: int = 2
    reach_bins: int = 12
    reach_beams: int = 12
    stride_bins: int = 2
    stride_beams: int = 2

    def __post_init__(self) -> None:
        for name in ('guard_bins', 'guard_beams', 'reach_bins', 'reach_beams'):
            if getattr(self, name) < 0:
                raise ValueError(f'{name} = {getattr(self, name)} must be >= 0')
        if self.stride_bins < 1 or self.stride_beams < 1:
            raise ValueError('strides must be >= 1')
        if self.reach_bins < self.guard_bins or self.reach_beams < self.guard_beams:
            raise ValueError('the reach must be at least the guard, in bins and in beams')
        if self.size == 0:
            raise ValueError(f'{self} holds no training cell')

    def _axis(self, reach: int, stride: int) -> np.ndarray:
        """1 at the multiples of ``stride`` in ``-reach..reach``, as a float32 vector."""
        off = np.arange(-reach, reach + 1)
        return (off % stride == 0).astype(np.float32)

    @cached_property
    def footprint(self) -> np.ndarray:
        """Boolean ``(2 reach_bins + 1, 2 reach_beams + 1)`` mask of the training cells."""
        outer = np.outer(self._axis(self.reach_bins, self.stride_bins), self._axis(self.reach_beams, self.stride_beams))
        i = np.arange(-self.reach_bins, self.reach_bins + 1)[:, None]
        j = np.arange(-self.reach_beams, self.reach_beams + 1)[None, :]
        guard = (np.abs(i) <= self.guard_bins) & (np.abs(j) <= self.guard_beams)
        return (outer > 0) & ~guard

    @cached_property
    def nearer(self) -> np.ndarray:
        """The footprint's nearer half (same shape, boolean)."""
        i = np.arange(-self.reach_bins, self.reach_bins + 1)[:, None]
        j = np.arange(-self.reach_beams, self.reach_beams + 1)[None, :]
        return self.footprint & ((i < 0) | ((i == 0) & (j < 0)))

    @property
    def size(self) -> int:
        """Training cells of a cell far from the sector's edges."""
        return int(np.count_nonzero(self.footprint))

    def _separable(self, nearer_only: bool) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """The footprint (or its nearer half) as a signed sum of outer products ``(rows, cols, sign)``."""
        rb, rw = self.reach_bins, self.reach_beams
        ob, ow = self._axis(rb, self.stride_bins), self._axis(rw, self.stride_beams)
        ib = np.arange(-rb, rb + 1)
        iw = np.arange(-rw, rw + 1)
        gb = ob * (np.abs(ib) <= self.guard_bins)
        gw = ow * (np.abs(iw) <= self.guard_beams)
        if not nearer_only:
            return [(ob, ow, 1.0), (gb, gw, -1.0)]
        before = (ib < 0).astype(np.float32)
        row0 = (ib == 0).astype(np.float32)
        left = (iw < 0).astype(np.float32)
        return [(ob * before, ow, 1.0), (gb * before, gw, -1.0), (ob * row0, ow * left, 1.0),
                (gb * row0, gw * left, -1.0)]

    def correlate(self, image: np.ndarray, nearer_only: bool = False) -> np.ndarray:
        """Sum of ``image`` over each cell's training cells (or their nearer half); outside the image
        counts 0. ``image`` is bins x beams, or bins x beams x channels (each channel summed alone,
        in one pass). float32 of the image's shape (sums of at most a few thousand cells)."""
        img = np.ascontiguousarray(image, dtype=np.float32)
        out = np.zeros(img.shape, np.float32)
        for rows, cols, sign in self._separable(nearer_only):
            if not rows.any() or not cols.any():
                continue
            # sepFilter2D correlates (no kernel flip): out[y, x] = sum k[i, j] img[y + i - r, x + j - r]
            part = cv2.sepFilter2D(img, cv2.CV_32F, _trimmed(cols), _trimmed(rows), borderType=cv2.BORDER_CONSTANT)
            if sign > 0:
                out += part.reshape(img.shape)
            else:
                out -= part.reshape(img.shape)
        return out

    def counts(self, shape: tuple[int, int], nearer_only: bool = False) -> np.ndarray:
        """Training cells of every cell of an image of ``shape`` with every cell measured (fewer near
        the edges). Cached per shape: a sensor sends one frame size."""
        key = (tuple(shape), nearer_only)
        cache = self.__dict__.setdefault('_counts', {})
        if key not in cache:
            if len(cache) > 8:
                cache.clear()
            cache[key] = np.rint(self.correlate(np.ones(shape, np.float32), nearer_only))
        return cache[key]

    @cached_property
    def sum_plan(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The whole window's sums as :func:`_ca_sums` takes them: the row terms of the training rows
        and of the guard (offsets and pair flags, :func:`_row_terms`), then the column terms of both
        (:func:`_column_terms`)."""
        (rows, cols, _), (guard_rows, guard_cols, _) = self._separable(False)
        return (*_row_terms(_trimmed(cols)), *_row_terms(_trimmed(guard_cols)), _column_terms(_trimmed(rows)),
                _column_terms(_trimmed(guard_rows)))


def _trimmed(kernel: np.ndarray) -> np.ndarray:
    """A centred kernel without the zero taps at both ends beyond its farthest non-zero tap (the
    centre stays the centre): a single-tap row costs one pass, not one per tap."""
    r = len(kernel) // 2
    reach = int(np.max(np.abs(np.flatnonzero(kernel) - r)))
    return np.ascontiguousarray(kernel[r - reach:r + reach + 1])


def _row_terms(taps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The additions of OpenCV's row pass for a symmetric 0/1 kernel ``taps``, in its order: offsets of the
    taps, and whether each term is the pair ``v[x - o] + v[x + o]`` rather than ``v[x + o]`` alone.

    A kernel of up to 5 taps is the centre tap followed by the symmetric pairs outward; a longer one
    its taps from left to right (what ``cv2.sepFilter2D`` does with float32 images; zero taps add
    exactly 0 and are left out)."""
    r = len(taps) // 2
    if len(taps) <= 5:
        offsets = [0] + [o for o in range(1, r + 1) if taps[r + o]]
        return np.array(offsets, np.int64), np.array([o > 0 for o in offsets], np.bool_)
    offsets = [i - r for i in range(len(taps)) if taps[i]]
    return np.array(offsets, np.int64), np.zeros(len(offsets), np.bool_)


def _column_terms(taps: np.ndarray) -> np.ndarray:
    """The offsets of OpenCV's column pass for a symmetric 0/1 kernel ``taps`` with its centre tap set:
    the centre, then ``h[y - o] + h[y + o]`` for each set tap ``o > 0`` outward."""
    r = len(taps) // 2
    return np.array([0] + [o for o in range(1, r + 1) if taps[r + o]], np.int64)


@kernel
def _row_sums(values, marks, offsets, pairs, pad, out_values, out_marks):
    """One row pass of the training or guard kernel over the zero-padded rows ``values`` and
    ``marks`` (``pad`` cells each side), in the order of :func:`_row_terms`."""
    n = uintp(out_values.shape[0])
    for x in range(n):
        out_values[x] = 0.0
        out_marks[x] = 0.0
    for g in range(offsets.shape[0]):
        o = offsets[g]
        b = uintp(pad + o)       # unsigned indices: no wrap-around test, so the loops vectorise
        if pairs[g]:
            a = uintp(pad - o)
            for x in range(n):
                out_values[x] += values[a + x] + values[b + x]
                out_marks[x] += marks[a + x] + marks[b + x]
        else:
            for x in range(n):
                out_values[x] += values[b + x]
                out_marks[x] += marks[b + x]


@kernel
def _column_sums(ring_values, ring_marks, offsets, y, out_values, out_marks):
    """One column pass at row ``y`` over row-pass results kept in a ring of ``2 reach + 1`` rows (row
    ``y`` in slot ``y % ring``), in the order of :func:`_column_terms`."""
    n = uintp(out_values.shape[0])
    ring = ring_values.shape[0]
    centre_v = ring_values[y % ring]
    centre_m = ring_marks[y % ring]
    for x in range(n):
        out_values[x] = centre_v[x]
        out_marks[x] = centre_m[x]
    for g in range(1, offsets.shape[0]):
        o = offsets[g]
        av, bv = ring_values[(y - o) % ring], ring_values[(y + o) % ring]
        am, bm = ring_marks[(y - o) % ring], ring_marks[(y + o) % ring]
        for x in range(n):
            out_values[x] += av[x] + bv[x]
            out_marks[x] += am[x] + bm[x]


@kernel
def _ca_sums(power, floor, row_outer, pair_outer, row_guard, pair_guard, col_outer, col_guard, total, count):
    """Sums of the measured cells' excess over ``floor`` (rule 1) and their counts over each cell's
    training cells: the training rectangle's sums less the guard's, by separable passes in
    OpenCV's order (:func:`_row_terms`, :func:`_column_terms`); ``total`` is clipped at 0. Row passes
    go into a ring of rows that the column pass reads as soon as it holds a row's neighbours."""
    n_rows, n_cols = power.shape
    pad_x = 0
    for o in row_outer:
        pad_x = max(pad_x, abs(o))
    for o in row_guard:
        pad_x = max(pad_x, abs(o))
    pad_y = max(col_outer.max(), col_guard.max())
    ring = 2 * pad_y + 1
    cut = np.float32(floor)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    values = np.zeros(n_cols + 2 * pad_x, np.float32)
    marks = np.zeros(n_cols + 2 * pad_x, np.float32)
    outer_v = np.zeros((ring, n_cols), np.float32)
    outer_m = np.zeros((ring, n_cols), np.float32)
    guard_v = np.zeros((ring, n_cols), np.float32)
    guard_m = np.zeros((ring, n_cols), np.float32)
    sum_v = np.empty(n_cols, np.float32)
    sum_m = np.empty(n_cols, np.float32)
    less_v = np.empty(n_cols, np.float32)
    less_m = np.empty(n_cols, np.float32)
    width = uintp(n_cols)
    for ahead in range(n_rows + pad_y):     # row pass of row `ahead`, column pass of row `ahead - pad_y`
        slot = (ahead + pad_y) % ring
        if ahead < n_rows:
            row = power[ahead]
            for x in range(width):
                p = row[x]
                ok = np.isfinite(p) and p != zero
                v = p
                if floor > 0:
                    v = p - cut
                    if not v > zero:
                        v = zero
                values[pad_x + x] = v if ok else zero
                marks[pad_x + x] = one if ok else zero
            _row_sums(values, marks, row_outer, pair_outer, pad_x, outer_v[slot], outer_m[slot])
            _row_sums(values, marks, row_guard, pair_guard, pad_x, guard_v[slot], guard_m[slot])
        else:                               # below the frame: rows of zeros
            outer_v[slot] = 0.0
            outer_m[slot] = 0.0
            guard_v[slot] = 0.0
            guard_m[slot] = 0.0
        y = ahead - pad_y
        if y < 0:
            continue
        _column_sums(outer_v, outer_m, col_outer, y + pad_y, sum_v, sum_m)
        _column_sums(guard_v, guard_m, col_guard, y + pad_y, less_v, less_m)
        out_t = total[y]
        out_c = count[y]
        for x in range(width):
            t = sum_v[x] - less_v[x]
            out_t[x] = t if t > zero else zero
            out_c[x] = sum_m[x] - less_m[x]


@dataclass(frozen=True, eq=False)
class WindowSums:
    """Per cell: sum and count of the measured training cells, in all and in the nearer half."""

    total: np.ndarray
    count: np.ndarray
    near_total: np.ndarray
    near_count: np.ndarray

    @property
    def far_total(self) -> np.ndarray:
        return self.total - self.near_total

    @property
    def far_count(self) -> np.ndarray:
        return self.count - self.near_count


def _excess(p: np.ndarray, ok: np.ndarray, floor: float) -> np.ndarray:
    """Measured cells' excess over the floor (rule 1), 0 where unmeasured."""
    if floor > 0:
        return np.where(ok, np.maximum(p - np.float32(floor), np.float32(0.0)), np.float32(0.0))
    return p if ok.all() else np.where(ok, p, np.float32(0.0))


def window_sums(power: np.ndarray, window: Window, halves: bool = False, floor: float = 0.0) -> WindowSums:
    """Sums and counts of the measured training cells of every cell of ``power`` (bins x beams,
    linear intensity); the sums are of their excess over ``floor`` (rule 1; 0: of the values).
    ``halves``: also the nearer half's (for greatest-of; otherwise those are empty). Counts are
    exact integers (float32); unmeasured cells add 0 to the sums."""
    p = np.asarray(power, dtype=np.float32)
    if not halves and p.ndim == 2 and p.size:
        total = np.empty(p.shape, np.float32)
        count = np.empty(p.shape, np.float32)
        _ca_sums(np.ascontiguousarray(p), float(floor), *window.sum_plan, total, count)
        return WindowSums(total, count, _NONE, _NONE)
    ok = measured(p)
    values = _excess(p, ok, floor)
    if ok.all():   # the counts depend on the frame size only
        total = window.correlate(values)
        count = window.counts(p.shape)
        if not halves:
            return WindowSums(np.maximum(total, 0.0), count, _NONE, _NONE)
        near = window.correlate(values, True)
        return WindowSums(np.maximum(total, 0.0), count, np.maximum(near, 0.0), window.counts(p.shape, True))
    both = np.stack([values, ok.astype(np.float32)], axis=-1)      # sums and counts in one pass
    total = window.correlate(both)
    if not halves:
        return WindowSums(np.maximum(total[..., 0], 0.0), np.rint(total[..., 1]), _NONE, _NONE)
    near = window.correlate(both, True)
    return WindowSums(np.maximum(total[..., 0], 0.0), np.rint(total[..., 1]), np.maximum(near[..., 0], 0.0),
                      np.rint(near[..., 1]))


_NONE = np.zeros((0, 0), np.float32)


def window_order(power: np.ndarray, window: Window, rank: int, floor: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The ``rank``-th smallest (1-based) of every cell's training cells (their excess over ``floor``,
    rule 1), unmeasured and outside cells taken as 0 (they sort first), and the number of those
    zeros among its training cells.

    A cell with ``m`` unmeasured training cells has as its value the ``(rank - m)``-th smallest of
    its ``size - m`` measured ones (0 when ``m >= rank``). Returns arrays of ``power``'s shape.
    """
    p = np.asarray(power, dtype=np.float32)
    ok = measured(p)
    values = _excess(p, ok, floor)
    stat = rank_filter(values, rank - 1, footprint=window.footprint, mode='constant', cval=0.0)
    missing = window.size - np.rint(window.correlate(ok.astype(np.float32)))
    return stat, missing

"""Table 2 features of square windows at many positions: the particle-rate path of the GPF tracker.

A *window region* of odd size ``n`` centred on pixel ``(r, c)`` is the ``n x n`` box of pixels
around it, every pixel of the box belonging to the region (a pixel without data counts with its
value 0 of the processed image), and its surrounding is the one-pixel ring around the box; pixels
outside the image hold no data. :meth:`WindowImage.features` returns, for K such windows, exactly
what :func:`~.features.patch_features` returns for the ``(n + 2) x (n + 2)`` patches (box plus
ring, :meth:`WindowImage.patches`) with the box as mask, i.e. the Table 2 definitions of
:mod:`.features` applied to those pixels (the tests check that the two agree), in a fraction of
the time, because a full box makes most of the general computation unnecessary:

* the shape features (f01, f02, f05, f10-f13) depend only on the mask, the same box for every
  window: computed once by :func:`~.features.patch_features` and repeated;
* the bounding rectangle of the box is the box, so it holds no background pixel, and f06 is the
  mean of the ring's pixels with data (the fallback of :func:`~.features.region_features`; if no
  ring pixel has data, the median of all the patches' pixels with data, as there);
* the moments of eq. (1) (f14-f20) are weighted sums over the box, a few small products per
  window, with Hu's invariants from :func:`~.features.hu_moments`;
* the co-occurrence counts (f21-f30) of a full box count all pixel pairs of the box in the four
  directions, with grey levels by :func:`~.features.quantise` (of the whole image once when a call
  asks for more window pixels than the image has), and the statistics from
  :func:`~.features.glcm_features`.

The sums over a window's pixels (box, ring, moments, pair counts) run in one compiled loop per
window (:func:`_window_sums`) on the image padded once in :class:`WindowImage`; the rest works on
:data:`CHUNK` windows at a time. 4,500 windows of 7 x 7 pixels with the paper's five features
(20, 17, 3, 6, 24) cost a few milliseconds.

The fallback of f06 (a window whose ring has no pixel with data) is the median of the pixels with
data of all the call's patches; a caller that looks up several particle clouds at once, or each
distinct window once, passes ``groups`` (the cloud of each window) and ``counts`` (how many
particles share it): the median is then that of the cloud's patches, each counted that many times,
exactly as if the cloud had been looked up alone with its repeated windows. Every feature of a
window is then the same to the last bit however the windows are batched, except f25-f29, whose
matrix products in :func:`~.features.glcm_features` round differently with the batch size.
"""
from __future__ import annotations

import functools

import numpy as np

from sonar_tracking.core.fls.features import (
    _DIRECTIONS,
    _GROUPS,
    N_FEATURES,
    FeatureConfig,
    _wanted,
    glcm_features,
    hu_moments,
    patch_features,
    quantise,
)
from sonar_tracking.core.jit import kernel

__all__ = ['WindowImage', 'window_features', 'WINDOW_SHAPE_FEATURES', 'CHUNK']

#: Windows computed together: larger batches spill out of the cache and run slower.
CHUNK = 1024
#: Co-occurrence cells (S^2 per window) computed together: bounds a chunk's memory for large S.
_GLCM_CELLS = 1 << 18

#: Features fixed by the mask alone: the same for every window of one size.
WINDOW_SHAPE_FEATURES = frozenset({1, 2, 5, 10, 11, 12, 13})


class WindowImage:
    """An image prepared for window features at many positions (see module docstring).

    ``image`` holds linear intensities of the processed image (0 = no data; NaN, infinite and
    negative values are taken as no data); ``max_size`` is the largest window size that will be
    asked for.
    """

    def __init__(self, image: np.ndarray, config: FeatureConfig | None = None, max_size: int = 31) -> None:
        img = np.asarray(image)
        if img.ndim != 2 or img.size == 0:
            raise ValueError(f'image must be a non-empty 2-D array, got shape {img.shape}')
        _check_size(max_size)
        self.config = config or FeatureConfig()
        self.shape = img.shape
        self.max_size = int(max_size)
        # A centre outside the image moves to the nearest place where its patch (half = size // 2 + 1
        # pixels either side) lies entirely outside (see _flat_index): up to 2 half + 1 pixels out.
        self.pad = 2 * (max_size // 2 + 1) + 1
        h, w = img.shape
        pw = w + 2 * self.pad
        self._width = pw
        padded = np.zeros((h + 2 * self.pad, pw))
        inner = padded[self.pad:self.pad + h, self.pad:self.pad + w]
        np.copyto(inner, img, casting='unsafe')
        bad = ~np.isfinite(inner)
        if bad.any():
            inner[bad] = 0.0
        np.maximum(inner, 0.0, out=inner)
        self._values = padded.ravel()
        self._offsets: dict[int, np.ndarray] = {}
        self._shape_rows: dict[tuple[int, tuple[int, ...]], np.ndarray] = {}
        self._buffers: dict[str, np.ndarray] = {}
        self._thresholds: np.ndarray | None = None
        self._levels: np.ndarray | None = None

    def _offsets_of(self, size: int) -> np.ndarray:
        off = self._offsets.get(size)
        if off is None:
            half = size // 2 + 1
            d = np.arange(-half, half + 1)
            off = self._offsets[size] = (d[:, None] * self._width + d[None, :]).ravel()
        return off

    def _centres(self, rows, cols, size: int) -> np.ndarray:
        """Flat indices ``(K,)`` of the window centres in the padded image."""
        h, w = self.shape
        half = size // 2 + 1
        # A centre far outside moves to where its patch is still entirely outside: the same (no) data.
        r = np.clip(np.asarray(rows).astype(np.int64), -half - 1, h + half) + self.pad
        c = np.clip(np.asarray(cols).astype(np.int64), -half - 1, w + half) + self.pad
        return r * self._width + c

    def _flat_index(self, rows, cols, size: int) -> np.ndarray:
        """Flat indices ``(K, (size + 2)^2)`` of the patches' pixels in the padded image.

        The index and patch arrays are kept between calls: fresh arrays of this size cost more in
        page faults than the features themselves.
        """
        r, c = self._check(rows, cols, size)
        off = self._offsets_of(size)
        idx = self._buffer('idx', (len(r), off.size), np.int64)
        np.add(self._centres(r, c, size)[:, None], off[None, :], out=idx)
        return idx

    def _check(self, rows, cols, size: int) -> tuple[np.ndarray, np.ndarray]:
        """The window centres as arrays, or ValueError saying what is wrong with the arguments."""
        _check_size(size)
        if size > self.max_size:
            raise ValueError(f'window size {size} exceeds max_size {self.max_size} of this WindowImage')
        r, c = np.asarray(rows), np.asarray(cols)
        if r.shape != c.shape or r.ndim != 1:
            raise ValueError(f'rows {r.shape} and cols {c.shape} must be 1-D arrays of one length')
        if r.size and (r.dtype.kind not in 'iu' or c.dtype.kind not in 'iu'):
            raise ValueError('window centres must be integer pixel indices (round fractional positions first)')
        return r, c

    def _buffer(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        """A kept array of at least this size, viewed with ``shape`` (its contents are garbage)."""
        n = int(np.prod(shape))
        buf = self._buffers.get(name)
        if buf is None or buf.size < n or buf.dtype != dtype:
            buf = self._buffers[name] = np.empty(n, dtype)
        return buf[:n].reshape(shape)

    def _gather(self, idx: np.ndarray, size: int) -> np.ndarray:
        out = self._buffer('values', idx.shape, self._values.dtype)
        np.take(self._values, idx, out=out)
        return out.reshape(len(idx), size + 2, size + 2)

    def patches(self, rows, cols, size: int) -> np.ndarray:
        """The ``(K, size + 2, size + 2)`` patches (box and ring) centred on pixels ``(rows, cols)``."""
        return self._gather(self._flat_index(rows, cols, size), size).copy()

    def features(self, rows, cols, size: int, features=None, groups=None, counts=None) -> np.ndarray:
        """Table 2 features ``(K, 30)`` (or ``(K, len(features))``) of the windows of odd ``size``
        centred on integer pixels ``(rows, cols)``; ``groups`` and ``counts`` (integers ``(K,)``) as
        in the module docstring."""
        wanted = _wanted(features)
        want = set(wanted)
        r, c = self._check(rows, cols, size)
        k = len(r)
        out = np.full((k, N_FEATURES + 1), np.nan)
        if k == 0:
            return out[:, wanted]
        ring = want & _GROUPS['background']
        background = np.empty(k) if ring else None
        has = np.empty(k, bool) if ring else None
        # The co-occurrence counts of a chunk, S^2 per window, stay within _GLCM_CELLS.
        chunk = max(1, min(CHUNK, _GLCM_CELLS // self.config.glcm_levels ** 2)) if want & _GROUPS['glcm'] else CHUNK
        for a in range(0, k, chunk):
            b = min(k, a + chunk)
            self._chunk(r[a:b], c[a:b], size, want, out[a:b], None if background is None else background[a:b],
                        None if has is None else has[a:b])
        if has is not None:   # the ring group was asked for
            if not has.all():
                self._fallback(r, c, size, has, background, groups, counts)
            mean = out[:, 3]
            out[:, 6] = background
            out[:, 7] = mean - background
            out[:, 8] = mean / background
            out[:, 9] = (mean - background) / (mean + background)
        return out[:, wanted]

    def _fallback(self, r, c, size, has, background, groups, counts) -> None:
        """Background of the windows whose ring has no pixel with data (module docstring)."""
        g = np.zeros(len(r), np.int64) if groups is None else np.asarray(groups)
        n = np.ones(len(r), np.int64) if counts is None else np.asarray(counts)
        for group in np.unique(g[~has]):
            sel = g == group
            p = np.repeat(self.patches(r[sel], c[sel], size), n[sel], axis=0)
            valid = p > 0
            background[sel & ~has] = float(np.median(p[valid])) if valid.any() else 1.0

    def _chunk(self, rows, cols, size, want, out, background, has) -> None:
        """Everything but the f06 fallback and f06-f09 for one chunk of windows (into ``out``)."""
        k = len(rows)
        centres = self._centres(rows, cols, size)
        flags = ((_STD if 4 in want else 0) | (_RING if background is not None else 0) |
                 (_HU if want & _GROUPS['hu'] else 0))
        glcm_cols = sorted(want & _GROUPS['glcm'])
        if glcm_cols:
            flags |= _GLCM
            if self._thresholds is None:
                self._thresholds = _level_thresholds(self.config)
            s = self.config.glcm_levels
            steps = np.array(_DIRECTIONS, np.int64) * self.config.glcm_distance
            if self._levels is None and k * size * size > self._values.size:
                # More window pixels than the image has: grey levels of the whole padded image, once.
                self._levels = np.empty(self._values.size, np.int64)
                _levels_into(self._values, self._thresholds, self._levels)
        else:
            s, steps = 1, np.zeros((0, 2), np.int64)
        levels = self._levels if glcm_cols and self._levels is not None else _NO_LEVELS
        box_sum, std = self._buffer('box_sum', (k,), np.float64), self._buffer('std', (k,), np.float64)
        ring, ring_count = self._buffer('ring', (k,), np.float64), self._buffer('ring_count', (k,), np.int64)
        mu = self._buffer('mu', (k, 7), np.float64)
        counts = self._buffer('glcm', (k if glcm_cols else 0, s, s), np.float64)
        thresholds = self._thresholds if glcm_cols else np.zeros(0)
        _window_sums(self._values, levels, centres, self._width, size, thresholds, steps, flags,
                     box_sum, std, ring, ring_count, mu, counts)

        shape = sorted(want & WINDOW_SHAPE_FEATURES)
        if shape:
            key = (size, tuple(shape))
            row = self._shape_rows.get(key)
            if row is None:
                m = size + 2
                mask = np.zeros((1, m, m), bool)
                mask[0, 1:-1, 1:-1] = True
                row = self._shape_rows[key] = patch_features(np.ones((1, m, m)), mask, self.config, shape)[0]
            out[:, shape] = row
        out[:, 3] = box_sum / float(size * size)
        if 4 in want:
            out[:, 4] = std
        if background is not None:
            # Pixels without data are 0, so the sum over the whole ring is the sum over those with data.
            np.greater(ring_count, 0, out=has)
            np.divide(ring, np.where(has, ring_count, 1), out=background)
        if flags & _HU:
            m00_safe = np.where(box_sum > 0, box_sum, 1.0)
            scale = {2: m00_safe ** 2, 3: m00_safe ** 2.5}
            eta = {pq: mu[:, j] / scale[int(pq[0]) + int(pq[1])] for j, pq in enumerate(_MOMENTS)}
            out[:, 14:21] = hu_moments(eta)
        if glcm_cols:
            out[:, glcm_cols] = glcm_features(counts, glcm_cols)


#: No grey-level image: :func:`_window_sums` quantises the pixels itself.
_NO_LEVELS = np.zeros(0, np.int64)
#: What :func:`_window_sums` computes besides the box sum (bit flags).
_STD, _RING, _HU, _GLCM = 1, 2, 4, 8
#: The central moments :func:`_window_sums` returns, in its order.
_MOMENTS = ('20', '02', '11', '30', '03', '21', '12')


@kernel
def _window_sums(values, levels, centres, width, size, thresholds, steps, flags,
                 box_sum, std, ring, ring_count, mu, glcm):
    """Per window of ``size`` x ``size`` pixels centred on flat index ``centres[k]`` of the padded
    image ``values`` (rows ``width`` long; ``levels``: the grey levels of its pixels, or empty to
    compute them here): the sum of the box; with the flags, the standard deviation
    (f04), the sum and count of the ring's pixels with data (f06), the central moments ``mu_pq`` of
    eq. (1) in the order of ``_MOMENTS`` (p along rows, about the intensity centroid; f14-f20), and the
    symmetric co-occurrence counts ``(S, S)`` of the box's pixel pairs ``steps`` apart (f21-f30, grey
    levels: how many ``thresholds`` each pixel reaches, i.e. :func:`~.features.quantise`)."""
    n_px = size * size
    half = size // 2
    s = glcm.shape[1]
    ss = s * s
    q = np.zeros(n_px, np.int64)
    qs = np.zeros(n_px, np.int64)
    pairs = np.zeros(2 * ss, np.int64)
    row_w = np.zeros(size)
    col_w = np.zeros(size)
    dy = np.zeros(size)
    for k in range(centres.size):
        top = centres[k] - half * width - half        # the box's first pixel
        total = 0.0
        for r in range(size):
            row_w[r] = 0.0
        for c in range(size):
            col_w[c] = 0.0
        for r in range(size):
            base = top + r * width
            for c in range(size):
                v = values[base + c]
                total += v
                row_w[r] += v
                col_w[c] += v
        m = total / n_px
        box_sum[k] = total
        if flags & _STD:
            acc = 0.0
            for r in range(size):
                base = top + r * width
                for c in range(size):
                    d = values[base + c] - m
                    acc += d * d
            var = acc / n_px
            std[k] = np.sqrt(var) if var > 0.0 else 0.0
        if flags & _RING:
            rs = 0.0
            rc = 0
            for c in range(-1, size + 1):
                for r in (-1, size):
                    v = values[top + r * width + c]
                    rs += v
                    rc += v > 0.0
            for r in range(size):
                for c in (-1, size):
                    v = values[top + r * width + c]
                    rs += v
                    rc += v > 0.0
            ring[k] = rs
            ring_count[k] = rc
        if flags & _HU:
            m00 = total if total > 0.0 else 1.0
            xc = 0.0
            yc = 0.0
            for i in range(size):
                xc += row_w[i] * i
                yc += col_w[i] * i
            xc /= m00
            yc /= m00
            mu20 = mu02 = mu11 = mu30 = mu03 = mu21 = mu12 = 0.0
            for c in range(size):
                dy[c] = c - yc
                mu02 += col_w[c] * dy[c] * dy[c]
                mu03 += col_w[c] * dy[c] * dy[c] * dy[c]
            for r in range(size):
                dx = r - xc
                mu20 += row_w[r] * dx * dx
                mu30 += row_w[r] * dx * dx * dx
                g1 = 0.0
                g2 = 0.0
                base = top + r * width
                for c in range(size):
                    v = values[base + c]
                    g1 += v * dy[c]
                    g2 += v * dy[c] * dy[c]
                mu11 += g1 * dx
                mu21 += g1 * dx * dx
                mu12 += g2 * dx
            mu[k, 0] = mu20
            mu[k, 1] = mu02
            mu[k, 2] = mu11
            mu[k, 3] = mu30
            mu[k, 4] = mu03
            mu[k, 5] = mu21
            mu[k, 6] = mu12
        if flags & _GLCM:
            for r in range(size):
                base = top + r * width
                for c in range(size):
                    v = levels[base + c] if levels.size else _level(values[base + c], thresholds)
                    q[r * size + c] = v
                    qs[r * size + c] = v * s
            # Two count tables, alternate pixels: consecutive increments of one cell (common in a
            # uniform window) would otherwise wait on each other.
            pairs.fill(0)
            n_pairs = 0
            for j in range(steps.shape[0]):
                dr, dc = steps[j, 0], steps[j, 1]
                off = dr * size + dc
                c0, c1 = max(0, -dc), size - max(0, dc)
                for r in range(max(0, -dr), size - max(0, dr)):
                    for i in range(r * size + c0, r * size + c1):
                        pairs[(i & 1) * ss + qs[i] + q[i + off]] += 1
                    n_pairs += c1 - c0 if c1 > c0 else 0
            if n_pairs == 0:   # no pair inside the box: the core pairs the region's first pixel with itself
                glcm[k] = 0.0
                glcm[k, q[0], q[0]] = 1.0
            else:
                for a in range(s):
                    for b in range(s):
                        ab, ba = a * s + b, b * s + a
                        glcm[k, a, b] = pairs[ab] + pairs[ss + ab] + pairs[ba] + pairs[ss + ba]


@kernel
def _level(v, thresholds):
    """The grey level of intensity ``v``: how many ``thresholds`` (ascending) it reaches, i.e.
    ``searchsorted(thresholds, v, 'right')``, which is :func:`~.features.quantise` of ``v``."""
    n_t = thresholds.size
    if n_t <= 16:                     # a few thresholds: count them without branches
        lev = 0
        for t in range(n_t):
            lev += thresholds[t] <= v
        return lev
    return np.searchsorted(thresholds, v, side='right')


@kernel
def _levels_into(values, thresholds, out):
    """:func:`_level` of every value (1-D) into ``out``."""
    for i in range(values.size):
        out[i] = _level(values[i], thresholds)


@functools.lru_cache(maxsize=16)
def _level_thresholds(config: FeatureConfig) -> np.ndarray:
    """The smallest intensity of each grey level 1..S-1 under :func:`~.features.quantise` (once per
    setting: the bisection takes milliseconds)."""
    s = config.glcm_levels
    step = (config.glcm_db_max - config.glcm_db_min) / s
    out = np.empty(s - 1)
    for k in range(1, s):
        lo = 10.0 ** ((config.glcm_db_min + (k - 1) * step) / 10.0)   # level < k (below the edge)
        hi = 10.0 ** ((config.glcm_db_min + (k + 1) * step) / 10.0)   # level >= k
        for _ in range(200):  # bisection on floats until lo and hi are neighbours
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            if quantise(np.array([mid]), config)[0] >= k:
                hi = mid
            else:
                lo = mid
        out[k - 1] = hi
    return out


def _check_size(size: int) -> None:
    if int(size) != size or size < 3 or size % 2 == 0:
        raise ValueError(f'window size {size} must be an odd integer >= 3')


def window_features(image: np.ndarray, rows, cols, size: int, config: FeatureConfig | None = None,
                    features=None) -> np.ndarray:
    """:meth:`WindowImage.features` for one call (prepare a :class:`WindowImage` to call many times)."""
    _check_size(size)
    return WindowImage(image, config, max(size, 3)).features(rows, cols, size, features)

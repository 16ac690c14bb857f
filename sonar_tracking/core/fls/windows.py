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
  directions: one ``bincount`` for all windows, grey levels from :func:`~.features.quantise` (of
  the whole image once when a call asks for more window pixels than the image has) and the
  statistics from :func:`~.features.glcm_features`.

The image is padded once in :class:`WindowImage`; each call then gathers the patches by flat
index into arrays kept between calls, :data:`CHUNK` windows at a time (so they stay in the cache).
300 windows of 11 x 11 pixels with the paper's five features (20, 17, 3, 6, 24) cost well under a
millisecond.

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

from .features import (_DIRECTIONS, _GROUPS, N_FEATURES, FeatureConfig, _wanted, glcm_features, hu_moments,
                       patch_features, quantise)

__all__ = ['WindowImage', 'window_features', 'WINDOW_SHAPE_FEATURES', 'CHUNK']

#: Windows gathered and computed together: larger batches spill out of the cache and run slower.
CHUNK = 1024

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

    def _flat_index(self, rows, cols, size: int) -> np.ndarray:
        """Flat indices ``(K, (size + 2)^2)`` of the patches' pixels in the padded image.

        The index and patch arrays are kept between calls: fresh arrays of this size cost more in
        page faults than the features themselves.
        """
        r, c = self._check(rows, cols, size)
        h, w = self.shape
        half = size // 2 + 1
        # A centre far outside moves to where its patch is still entirely outside: the same (no) data.
        r = np.clip(r.astype(np.int64), -half - 1, h + half) + self.pad
        c = np.clip(c.astype(np.int64), -half - 1, w + half) + self.pad
        off = self._offsets_of(size)
        idx = self._buffer('idx', (len(r), off.size), np.int64)
        np.add((r * self._width + c)[:, None], off[None, :], out=idx)
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

    def _levels_of(self, values: np.ndarray) -> np.ndarray:
        """:func:`~.features.quantise` of ``values``, by comparison with the smallest intensity of
        each grey level (found once from ``quantise`` itself, which is monotone in the intensity),
        several times faster than the logarithms."""
        if self._thresholds is None:
            self._thresholds = _level_thresholds(self.config)
        t = self._thresholds
        flat = np.ascontiguousarray(values).reshape(-1)
        if t.size > 16:
            return np.searchsorted(t, flat, side='right').reshape(values.shape)
        out = self._buffer('levels', flat.shape, np.int8)
        above = self._buffer('above', flat.shape, np.bool_)
        out.fill(0)
        for v in t:
            np.greater_equal(flat, v, out=above)
            np.add(out, above.view(np.int8), out=out)
        return out.reshape(values.shape)

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
        if self._levels is None and want & _GROUPS['glcm'] and k * size * size > self._values.size:
            # More window pixels than the image has: grey levels of the whole padded image, once.
            self._levels = self._levels_of(self._values).copy()
        for a in range(0, k, CHUNK):
            b = min(k, a + CHUNK)
            self._chunk(r[a:b], c[a:b], size, want, out[a:b], None if background is None else background[a:b],
                        None if has is None else has[a:b])
        if ring:
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
        idx = self._flat_index(rows, cols, size)
        k = len(idx)
        m = size + 2
        p = self._gather(idx, size)
        box = p[:, 1:-1, 1:-1]
        n_px = float(size * size)
        box_sum = box.sum(axis=(1, 2))
        mean = box_sum / n_px

        shape = sorted(want & WINDOW_SHAPE_FEATURES)
        if shape:
            key = (size, tuple(shape))
            row = self._shape_rows.get(key)
            if row is None:
                mask = np.zeros((1, m, m), bool)
                mask[0, 1:-1, 1:-1] = True
                row = self._shape_rows[key] = patch_features(np.ones((1, m, m)), mask, self.config, shape)[0]
            out[:, shape] = row
        out[:, 3] = mean
        if 4 in want:
            dev = box.reshape(k, -1) - mean[:, None]
            out[:, 4] = np.sqrt(np.clip(np.einsum('ki,ki->k', dev, dev) / n_px, 0.0, None))

        if background is not None:
            ring_sum = p.sum(axis=(1, 2)) - box_sum
            valid = p > 0
            ring_cnt = (np.count_nonzero(valid, axis=(1, 2)) - np.count_nonzero(box > 0, axis=(1, 2))).astype(float)
            # Pixels without data are 0, so the sum over the whole ring is the sum over those with data.
            np.greater(ring_cnt, 0.5, out=has)
            np.divide(ring_sum, np.where(has, ring_cnt, 1.0), out=background)

        if want & _GROUPS['hu']:
            i = np.arange(size, dtype=np.float64)
            row_w = box.sum(axis=2)       # weight per row (p runs along rows)
            col_w = box.sum(axis=1)       # weight per column (q along columns)
            m00_safe = np.where(box_sum > 0, box_sum, 1.0)
            dx = i[None, :] - (row_w @ i / m00_safe)[:, None]
            dy = i[None, :] - (col_w @ i / m00_safe)[:, None]
            dx2, dy2 = dx * dx, dy * dy
            g = np.matmul(box, np.stack([dy, dy2], axis=2))     # (K, n, 2): sums along columns of f dy, f dy^2
            mu = {'20': np.einsum('ki,ki->k', row_w, dx2), '02': np.einsum('ki,ki->k', col_w, dy2),
                  '11': np.einsum('ki,ki->k', g[:, :, 0], dx), '30': np.einsum('ki,ki->k', row_w * dx2, dx),
                  '03': np.einsum('ki,ki->k', col_w * dy2, dy), '21': np.einsum('ki,ki->k', g[:, :, 0], dx2),
                  '12': np.einsum('ki,ki->k', g[:, :, 1], dx)}
            scale = {2: m00_safe ** 2, 3: m00_safe ** 2.5}
            eta = {pq: v / scale[int(pq[0]) + int(pq[1])] for pq, v in mu.items()}
            out[:, 14:21] = hu_moments(eta)

        glcm_cols = sorted(want & _GROUPS['glcm'])
        if glcm_cols:
            s = self.config.glcm_levels
            d = self.config.glcm_distance
            if self._levels is None:
                q = self._levels_of(box)
            else:
                q = self._buffer('q', idx.shape, self._levels.dtype)
                np.take(self._levels, idx, out=q)
                q = q.reshape(k, m, m)[:, 1:-1, 1:-1]
            # Code of a pair (a, b) of window j: (j S + a) S + b; the first factor once per pixel.
            first = self._buffer('first', q.shape, np.intp)
            first[...] = q
            first *= s
            first += (np.arange(k, dtype=np.intp) * (s * s))[:, None, None]
            parts = []
            for dr, dc in _DIRECTIONS:
                dr, dc = d * dr, d * dc
                # Pixel a and its partner a + (dr, dc), both inside the box.
                r0, r1 = max(0, -dr), size - max(0, dr)
                c0, c1 = max(0, -dc), size - max(0, dc)
                if r1 > r0 and c1 > c0:
                    parts.append((slice(r0, r1), slice(c0, c1), slice(r0 + dr, r1 + dr), slice(c0 + dc, c1 + dc)))
            if parts:
                n_codes = sum(k * (p_[0].stop - p_[0].start) * (p_[1].stop - p_[1].start) for p_ in parts)
                codes = self._buffer('codes', (n_codes,), np.intp)
                pos = 0
                for ra, ca, rb, cb in parts:
                    a = first[:, ra, ca]
                    np.add(a, q[:, rb, cb], out=codes[pos:pos + a.size].reshape(a.shape))
                    pos += a.size
                h = np.bincount(codes, minlength=k * s * s).reshape(k, s, s)
                h = h + h.transpose(0, 2, 1)
            else:  # no pair inside the box: the core pairs the region's first pixel with itself
                h = np.zeros((k, s, s), np.int64)
                h[np.arange(k), q[:, 0, 0], q[:, 0, 0]] = 1
            out[:, glcm_cols] = glcm_features(h, glcm_cols)


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

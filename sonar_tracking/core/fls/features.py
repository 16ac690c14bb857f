"""The 30 region features of FLS paper Table 2 (f01..f30), for many regions at once.

Notation of the paper (§3.1): region ``R_k`` of ``N^o`` pixels, its edge of ``N_e^o`` pixels, its
minimum outer (bounding) rectangle of ``m x n`` pixels, ``f(i, j)`` the intensity at row ``i`` and
column ``j`` of the processed image, ``S`` grey levels, ``h(i, j)`` the normalised grey-level
co-occurrence matrix (GLCM) of the region.

=====  =========================================================================================
f01    area ``A0 = N^o`` [pixels]
f02    perimeter ``P0 = N_e^o``: region pixels with a 4-neighbour outside the region [pixels]
f03    mean intensity ``I0`` of the region
f04    intensity standard deviation of the region (the name in Table 2; its formula prints the
       variance without the square root, which we read as a typo)
f05    compactness ``4 pi A0 / P0^2``
f06    background mean ``B0``: mean of the pixels of the bounding rectangle not in ``R_k``
f07    ``I0 - B0``;  f08 ``I0 / B0``;  f09 ``(I0 - B0) / (I0 + B0)``
f10    ``SM1 = mu2^(1/2) / m1`` of the distances ``D`` from the edge pixels to the region centroid
       (``m1`` their mean, ``mu_r`` their r-th central moment: Gupta and Srinath's contour
       sequence moments)
f11    ``SM2 = mu3^(1/3) / m1`` (Table 2's garbled exponents read as 3 and 1/3, the sequence of
       SM1 and SM3; the cube root keeps the sign of ``mu3``)
f12    ``SM3 = mu4^(1/4) / m1``;  f13 ``SM4 = SM3 - SM1``
f14-20 Hu's moment invariants ``M1..M7`` from the normalised central moments of eq. (1),
       weighted by the intensity of the region's pixels, ``p`` along rows ``i`` and ``q`` along
       columns ``j``. Row 20 of Table 2 prints ``+`` between the two terms of ``M7`` and
       ``(eta12 + eta03)`` in the first bracket; with those it is not an invariant, so we use Hu's
       ``M7`` (as OpenCV does): ``(3 eta21 - eta03)(eta30 + eta12)[(eta30 + eta12)^2 -
       3 (eta21 + eta03)^2] - (eta30 - 3 eta12)(eta21 + eta03)[3 (eta30 + eta12)^2 -
       (eta21 + eta03)^2]``. ``M7`` changes sign under reflection.
f21    inertia (contrast) ``sum (i-j)^2 h``;  f22 entropy ``-sum h ln h``;  f23 angular second moment
       ``sum h^2``;  f24 inverse difference moment ``sum h / (1 + (i-j)^2)``
f25    correlation: blank in Table 2; we use Haralick's ``sum (i - mu_x)(j - mu_y) h / (sigma_x
       sigma_y)`` (1 when a marginal has no spread, as scikit-image does)
f26    variance ``sum (i - mu_x)^2 h``
f27    sum average ``sum_k k p_{x+y}(k)``, ``k = 2..2S`` with grey levels counted from 1 as in
       Haralick (Table 2 mixes 0-based sums with these limits);  f28 sum entropy
       ``-sum p_{x+y} ln p_{x+y}``;  f29 sum variance ``sum (k - f27)^2 p_{x+y}(k)`` (Table 2 uses
       the sum average here, the correction of Haralick's misprint)
f30    difference entropy ``-sum p_{x-y} ln p_{x-y}``, ``k = |i - j| = 0..S-1``
=====  =========================================================================================

Choices where the paper is silent:

* Intensities are those of the processed image (linear, 1 = background). Pixels that hold no data
  (NaN or 0: outside the sonar's fan) are never background in f06; if the bounding rectangle holds
  no background pixel (a region filling its rectangle), the one-pixel ring around it is used, and
  failing that the median of the image.
* Grey levels for the GLCM: the intensity in dB is quantised to ``S = glcm_levels`` levels between
  ``glcm_db_min`` and ``glcm_db_max`` (clipped), the same mapping for every region, so the
  texture features compare regions of different brightness. Echo intensity spans decades, so dB.
* The GLCM counts pixel pairs at distance ``glcm_distance`` in the four directions 0, 45, 90 and
  135 degrees with both pixels in the region, symmetrically (each pair both ways), summed over the
  directions and normalised: a rotation-averaged texture. A one-pixel region has no pair; its
  GLCM is taken as the pixel paired with itself.
* Distances and coordinates are in pixels, as in the paper; a region with no pixel gives NaN.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.records import FEATURE_NAMES

__all__ = ['FeatureConfig', 'region_features', 'patch_features', 'quantise', 'glcm', 'glcm_features',
           'hu_moments', 'N_FEATURES', 'FEATURE_NAMES', 'FEATURE_LABELS']

N_FEATURES = 30

#: Short names of f01..f30 (Table 2).
FEATURE_LABELS = (
    'area', 'perimeter', 'mean intensity', 'intensity std', 'compactness', 'background mean',
    'contrast I-B', 'contrast I/B', 'contrast (I-B)/(I+B)', 'SM1', 'SM2', 'SM3', 'SM4',
    'M1', 'M2', 'M3', 'M4', 'M5', 'M6', 'M7',
    'GLCM inertia', 'GLCM entropy', 'GLCM ASM', 'GLCM IDM', 'GLCM correlation', 'GLCM variance',
    'GLCM sum average', 'GLCM sum entropy', 'GLCM sum variance', 'GLCM difference entropy',
)

# Pixel offsets (row, col) of the four GLCM directions 0, 45, 90, 135 degrees (the same four
# directions as scikit-image; the sign of an offset does not matter for a symmetric matrix).
_DIRECTIONS = ((0, 1), (-1, 1), (-1, 0), (-1, -1))


@dataclass(frozen=True)
class FeatureConfig(Config):
    """Settings of the region features (grey-level co-occurrence)."""

    glcm_levels: int = setting(8, 'grey levels S of the co-occurrence matrix (features 21-30)', low=2, high=256)
    glcm_db_min: float = setting(0.0, 'intensity mapped to the lowest grey level (re background)', unit='dB',
                                 low=-60.0, high=120.0)
    glcm_db_max: float = setting(24.0, 'intensity mapped to the highest grey level (re background)', unit='dB',
                                 low=-60.0, high=120.0)
    glcm_distance: int = setting(1, 'pixel distance of co-occurring pairs', unit='px', low=1, high=32)

    def validate(self) -> None:
        if self.glcm_db_max <= self.glcm_db_min:
            raise ConfigError(f'glcm_db_max = {self.glcm_db_max} must exceed glcm_db_min = {self.glcm_db_min}')


def quantise(values: np.ndarray, config: FeatureConfig) -> np.ndarray:
    """Grey levels ``0..S-1`` (int32) of linear intensities: dB mapped linearly, clipped."""
    s = config.glcm_levels
    v = np.asarray(values, dtype=np.float64)
    with np.errstate(divide='ignore', invalid='ignore'):
        db = 10.0 * np.log10(np.where(v > 0, v, np.nan))
    q = np.floor((db - config.glcm_db_min) * (s / (config.glcm_db_max - config.glcm_db_min)))
    return np.clip(np.nan_to_num(q, nan=0.0), 0, s - 1).astype(np.int32)


def hu_moments(eta: dict[str, np.ndarray]) -> np.ndarray:
    """Hu's seven invariants (Table 2, rows 14-20) from normalised central moments ``eta['pq']``
    (arrays of equal shape); returns shape ``(..., 7)``."""
    n20, n02, n11 = eta['20'], eta['02'], eta['11']
    n30, n03, n21, n12 = eta['30'], eta['03'], eta['21'], eta['12']
    a, b = n30 + n12, n21 + n03
    m1 = n20 + n02
    m2 = (n20 - n02) ** 2 + 4.0 * n11 ** 2
    m3 = (n30 - 3.0 * n12) ** 2 + (3.0 * n21 - n03) ** 2
    m4 = a ** 2 + b ** 2
    m5 = (n30 - 3.0 * n12) * a * (a ** 2 - 3.0 * b ** 2) + (3.0 * n21 - n03) * b * (3.0 * a ** 2 - b ** 2)
    m6 = (n20 - n02) * (a ** 2 - b ** 2) + 4.0 * n11 * a * b
    m7 = (3.0 * n21 - n03) * a * (a ** 2 - 3.0 * b ** 2) - (n30 - 3.0 * n12) * b * (3.0 * a ** 2 - b ** 2)
    return np.stack([m1, m2, m3, m4, m5, m6, m7], axis=-1)


def _neighbours(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int], dr: int, dc: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices of the pixels ``(dr, dc)`` away from pixels ``(rows, cols)``, and whether they exist."""
    h, w = shape
    r, c = rows + dr, cols + dc
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    return np.where(inside, r * w + c, 0), inside


def glcm(levels: np.ndarray, labels: np.ndarray, n: int, s: int, distance: int = 1) -> np.ndarray:
    """Co-occurrence counts ``(n, s, s)`` of each region's pixel pairs (both in the region) at
    ``distance`` in the four directions, symmetric, summed over directions (not normalised).

    ``levels`` are the grey levels ``0..s-1`` of the image, ``labels`` its regions ``1..n``.
    """
    flat_lab, flat_lev = labels.ravel(), levels.ravel()
    idx = np.flatnonzero(flat_lab)
    rows, cols = np.divmod(idx, labels.shape[1])
    own = flat_lab[idx].astype(np.int64)
    q = flat_lev[idx].astype(np.int64)
    counts = np.zeros((n + 1) * s * s, np.int64)
    for dr, dc in _DIRECTIONS:
        nb, inside = _neighbours(rows, cols, labels.shape, distance * dr, distance * dc)
        same = inside & (flat_lab[nb] == own)
        code = (own[same] * s + q[same]) * s + flat_lev[nb[same]]
        counts += np.bincount(code, minlength=counts.size)
    h = counts.reshape(n + 1, s, s)[1:]
    return h + h.transpose(0, 2, 1)


def _box_pixels(r0: np.ndarray, r1: np.ndarray, c0: np.ndarray, c1: np.ndarray, width: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Every pixel of inclusive boxes ``k``: ``(k of each pixel, its flat index)``."""
    hs, ws = r1 - r0 + 1, c1 - c0 + 1
    sizes = np.where((hs > 0) & (ws > 0), hs * ws, 0)
    owner = np.repeat(np.arange(sizes.size), sizes)
    start = np.repeat(np.cumsum(sizes) - sizes, sizes)
    local = np.arange(owner.size) - start
    wk = ws[owner]
    return owner, (r0[owner] + local // wk) * width + c0[owner] + local % wk


def glcm_features(h: np.ndarray, features=None) -> np.ndarray:
    """Table 2 features 21-30 of co-occurrence matrices ``(n, S, S)`` (normalised here): ``(n, 10)``,
    or with ``features`` (Table 2 numbers within 21-30) ``(n, len(features))``, computing only those."""
    wanted = list(range(21, 31)) if features is None else [int(f) for f in features]
    if not wanted or any(not 21 <= f <= 30 for f in wanted):
        raise ValueError(f'GLCM features {wanted} must be Table 2 numbers 21..30')
    need = set(wanted)
    h = np.asarray(h, dtype=np.float64)
    total = h.sum(axis=(1, 2), keepdims=True)
    h = h / np.where(total > 0, total, 1.0)
    s = h.shape[-1]
    i = np.arange(s, dtype=np.float64)[:, None]
    j = np.arange(s, dtype=np.float64)[None, :]
    d2 = (i - j) ** 2
    out = {}

    def entropy(p: np.ndarray, axes) -> np.ndarray:
        return -np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0), axis=axes)

    if 21 in need:
        out[21] = np.sum(d2 * h, axis=(1, 2))                    # inertia
    if 22 in need:
        out[22] = entropy(h, (1, 2))
    if 23 in need:
        out[23] = np.sum(h * h, axis=(1, 2))                      # angular second moment
    if 24 in need:
        out[24] = np.sum(h / (1.0 + d2), axis=(1, 2))             # inverse difference moment
    if need & {25, 26}:
        px, py = h.sum(axis=2), h.sum(axis=1)
        lv = np.arange(s, dtype=np.float64)
        mux, muy = px @ lv, py @ lv
        if 25 in need:
            varx = px @ (lv ** 2) - mux ** 2
            vary = py @ (lv ** 2) - muy ** 2
            cov = np.einsum('kij,i,j->k', h, lv, lv) - mux * muy
            sd = np.sqrt(np.clip(varx, 0, None) * np.clip(vary, 0, None))
            out[25] = np.where(sd > 1e-15, cov / np.where(sd > 1e-15, sd, 1.0), 1.0)
        if 26 in need:
            out[26] = np.einsum('kij,ki->k', h, (lv[None, :] - mux[:, None]) ** 2)
    # Sum and difference distributions: k = (i+1) + (j+1) = 2..2S, and |i - j| = 0..S-1.
    # p_{x+y} and p_{x-y} by summing h over the anti-diagonals and the |i - j| bands (0/1 matrices).
    cells = np.arange(s * s)
    flat = h.reshape(h.shape[0], -1)
    if need & {27, 28, 29}:
        to_sum = np.zeros((s * s, 2 * s - 1))
        to_sum[cells, (i + j).astype(np.int64).ravel()] = 1.0
        psum = flat @ to_sum
        k = np.arange(2, 2 * s + 1, dtype=np.float64)
        sum_avg = psum @ k
        out[27] = sum_avg
        if 28 in need:
            out[28] = entropy(psum, 1)
        if 29 in need:
            out[29] = np.sum((k[None, :] - sum_avg[:, None]) ** 2 * psum, axis=1)
    if 30 in need:
        to_dif = np.zeros((s * s, s))
        to_dif[cells, np.abs(i - j).astype(np.int64).ravel()] = 1.0
        out[30] = entropy(flat @ to_dif, 1)
    return np.stack([out[f] for f in wanted], axis=1)


_GROUPS = {  # feature numbers -> the group of computations they need
    'edge': {2, 5, 10, 11, 12, 13}, 'background': {6, 7, 8, 9}, 'shape': {10, 11, 12, 13},
    'hu': set(range(14, 21)), 'glcm': set(range(21, 31)),
}


def _wanted(features) -> list[int]:
    if features is None:
        return list(range(1, N_FEATURES + 1))
    out = [int(f) for f in features]
    bad = [f for f in out if not 1 <= f <= N_FEATURES]
    if bad or not out:
        raise ValueError(f'features {list(features)} must be Table 2 numbers 1..{N_FEATURES}')
    return out


def region_features(image: np.ndarray, labels: np.ndarray, n: int | None = None,
                    config: FeatureConfig | None = None, features=None) -> np.ndarray:
    """Features of Table 2 of regions ``1..n`` of ``labels`` on ``image``.

    Returns ``(n, 30)`` (f01..f30), or with ``features`` (Table 2 numbers, e.g. the selected
    subset) ``(n, len(features))`` in that order, computing only what those need. ``image`` holds
    linear intensities (NaN or 0 = no data); ``labels`` int, 0 = no region. Rows of regions
    without pixels are NaN. All regions are computed together from their pixel lists, so the cost
    grows with the number of region pixels, not with the image.
    """
    config = config or FeatureConfig()
    wanted = _wanted(features)
    need = {g for g, members in _GROUPS.items() if members & set(wanted)}
    img = np.asarray(image, dtype=np.float64)
    lab = np.asarray(labels)
    if img.ndim != 2 or lab.shape != img.shape:
        raise ValueError(f'image {img.shape} and labels {lab.shape} must be 2-D arrays of one shape')
    lab = lab.astype(np.int64, copy=False)
    if n is None:
        n = int(lab.max(initial=0))
    out = np.full((n, N_FEATURES + 1), np.nan)  # column 0 unused: columns are Table 2 numbers
    if n == 0:
        return out[:, wanted]
    h_img, w_img = img.shape
    flat_lab, flat_img = lab.ravel(), img.ravel()
    idx = np.flatnonzero(flat_lab)
    own = flat_lab[idx]
    if own.size and own.max() > n:
        raise ValueError(f'labels go up to {own.max()} but n = {n}')
    ri, ci = np.divmod(idx, w_img)
    rows, cols = ri.astype(np.float64), ci.astype(np.float64)
    f = flat_img[idx]
    bins = n + 1

    def count(w=None, who=own) -> np.ndarray:
        return np.bincount(who, weights=w, minlength=bins)[1:]

    area = count()
    present = area > 0
    safe_area = np.where(present, area, 1.0)

    # (a) basic: area, mean, standard deviation; edge pixels (4-neighbourhood), compactness.
    mean = count(f) / safe_area
    dev = f - mean[own - 1]
    out[:, 1], out[:, 3] = area, mean
    out[:, 4] = np.sqrt(np.clip(count(dev * dev) / safe_area, 0.0, None))
    if 'edge' in need:
        edge = np.zeros(idx.size, bool)
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            nb, inside = _neighbours(ri, ci, lab.shape, dr, dc)
            edge |= ~inside | (flat_lab[nb] != own)
        perim = count(who=own[edge]).astype(np.float64)
        out[:, 2] = perim
        out[:, 5] = 4.0 * np.pi * area / np.where(perim > 0, perim, 1.0) ** 2

    # (a, b) f06 background mean over the bounding rectangle (pixels not in the region, with data),
    # and the contrasts.
    if 'background' in need:
        big = np.iinfo(np.int64).max
        r0, c0 = np.full(bins, big, np.int64), np.full(bins, big, np.int64)
        r1, c1 = np.full(bins, -1, np.int64), np.full(bins, -1, np.int64)
        np.minimum.at(r0, own, ri)
        np.minimum.at(c0, own, ci)
        np.maximum.at(r1, own, ri)
        np.maximum.at(c1, own, ci)
        r0, c0, r1, c1 = (a[1:] for a in (r0, c0, r1, c1))

        def background_of(a0, b0, a1, b1) -> tuple[np.ndarray, np.ndarray]:
            k, pix = _box_pixels(a0, a1, b0, b1, w_img)
            v = flat_img[pix]
            use = (flat_lab[pix] != k + 1) & np.isfinite(v) & (v > 0)
            return (np.bincount(k[use], weights=v[use], minlength=n),
                    np.bincount(k[use], minlength=n).astype(float))

        b_sum, b_cnt = background_of(r0, c0, r1, c1)
        ring = present & (b_cnt < 0.5)
        if ring.any():
            # The one-pixel ring around the rectangle; other regions' boxes made empty.
            e0 = np.where(ring, np.maximum(r0 - 1, 0), 0)
            f0 = np.where(ring, np.maximum(c0 - 1, 0), 0)
            e1 = np.where(ring, np.minimum(r1 + 1, h_img - 1), -1)
            f1 = np.where(ring, np.minimum(c1 + 1, w_img - 1), -1)
            r_sum, r_cnt = background_of(e0, f0, e1, f1)
            b_sum, b_cnt = np.where(ring, r_sum, b_sum), np.where(ring, r_cnt, b_cnt)
        fallback = 1.0
        if (present & (b_cnt < 0.5)).any():
            valid = np.isfinite(img) & (img > 0)
            fallback = float(np.median(img[valid])) if valid.any() else 1.0
        background = np.where(b_cnt > 0.5, b_sum / np.where(b_cnt > 0.5, b_cnt, 1.0), fallback)
        out[:, 6] = background
        out[:, 7] = mean - background
        out[:, 8] = mean / background
        out[:, 9] = (mean - background) / (mean + background)

    # (c) shape moments of the edge-to-centroid distances (binary centroid).
    if 'shape' in need:
        cr, cc = count(rows) / safe_area, count(cols) / safe_area
        e_own = own[edge]
        dist = np.hypot(rows[edge] - cr[e_own - 1], cols[edge] - cc[e_own - 1])
        e_cnt = count(who=e_own).astype(np.float64)
        e_safe = np.where(e_cnt > 0, e_cnt, 1.0)
        m1 = count(dist, e_own) / e_safe
        d = dist - m1[e_own - 1]
        d2 = d * d
        mu2, mu3, mu4 = (count(w, e_own) / e_safe for w in (d2, d2 * d, d2 * d2))
        m1_safe = np.where(m1 > 0, m1, 1.0)
        sm1 = np.where(m1 > 0, np.sqrt(np.clip(mu2, 0, None)) / m1_safe, 0.0)
        sm3 = np.where(m1 > 0, np.clip(mu4, 0, None) ** 0.25 / m1_safe, 0.0)
        out[:, 10], out[:, 12], out[:, 13] = sm1, sm3, sm3 - sm1
        out[:, 11] = np.where(m1 > 0, np.cbrt(mu3) / m1_safe, 0.0)

    # (d) moment invariants from eq. (1): intensity-weighted, p along rows, q along columns.
    if 'hu' in need:
        fw = np.where(np.isfinite(f), f, 0.0)
        m00 = count(fw)
        m00_safe = np.where(m00 > 0, m00, 1.0)
        xb, yb = count(rows * fw) / m00_safe, count(cols * fw) / m00_safe
        dx, dy = rows - xb[own - 1], cols - yb[own - 1]
        px = {0: 1.0, 1: dx, 2: dx * dx}
        px[3] = px[2] * dx
        py = {0: 1.0, 1: dy, 2: dy * dy}
        py[3] = py[2] * dy
        eta = {f'{p}{q}': count(px[p] * py[q] * fw) / m00_safe ** ((p + q + 2) / 2.0)
               for p, q in ((2, 0), (0, 2), (1, 1), (3, 0), (0, 3), (2, 1), (1, 2))}
        out[:, 14:21] = hu_moments(eta)

    # (e) grey-level co-occurrence statistics.
    if 'glcm' in need:
        s = config.glcm_levels
        levels = np.zeros(img.shape, np.int16 if s <= 32767 else np.int32)
        levels.ravel()[idx] = quantise(f, config)
        h = glcm(levels, lab, n, s, config.glcm_distance).astype(np.float64)
        lonely = (h.sum(axis=(1, 2)) == 0) & present
        if lonely.any():  # a one-pixel region: the pixel paired with itself
            first = np.full(bins, own.size, np.int64)
            np.minimum.at(first, own, np.arange(own.size))  # each region's first pixel
            ql = levels.ravel()[idx[first[1:][lonely]]]
            h[np.flatnonzero(lonely), ql, ql] = 1.0
        glcm_cols = sorted(set(wanted) & _GROUPS['glcm'])
        out[:, glcm_cols] = glcm_features(h, glcm_cols)

    out[~present] = np.nan
    return out[:, wanted]


def patch_features(patches: np.ndarray, masks: np.ndarray, config: FeatureConfig | None = None,
                   features=None) -> np.ndarray:
    """Features f01..f30 of ``K`` image patches ``(K, h, w)``, each over the pixels of its mask
    ``(K, h, w)`` bool (pixels that hold data): shape ``(K, 30)``, or ``(K, len(features))`` for
    the Table 2 numbers ``features``; NaN rows for empty masks. For computing features at many
    positions (particles) in one call; the patches are stacked with a no-data row between them and
    handed to :func:`region_features`, so the results are exactly those of the same pixels in an
    image."""
    p = np.asarray(patches, dtype=np.float64)
    m = np.asarray(masks, dtype=bool)
    if p.ndim != 3 or m.shape != p.shape:
        raise ValueError(f'patches {p.shape} and masks {m.shape} must be 3-D arrays (K, h, w) of one shape')
    k, h, w = p.shape
    tall = np.full((k, h + 1, w), np.nan)
    tall[:, :h] = p
    lab = np.zeros((k, h + 1, w), np.int64)
    lab[:, :h] = np.where(m, np.arange(1, k + 1)[:, None, None], 0)
    return region_features(tall.reshape(k * (h + 1), w), lab.reshape(k * (h + 1), w), k, config, features)

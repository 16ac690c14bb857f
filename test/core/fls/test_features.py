"""Table 2 features f01..f30 against independent computations on synthetic shapes.

Moments: OpenCV ``moments``/``HuMoments``; boundaries and co-occurrence: scikit-image
``find_boundaries``, ``graycomatrix``, ``graycoprops``; the rest straight from the Table 2
formulas with plain numpy over the region's pixels (one region at a time, no shared code).
"""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from skimage.feature import graycomatrix, graycoprops
from skimage.segmentation import find_boundaries

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.fls import PAPER_FEATURES, FeatureConfig, patch_features, region_features
from sonar_tracking.core.fls.features import FEATURE_LABELS, quantise

CFG = FeatureConfig(glcm_levels=8, glcm_db_min=0.0, glcm_db_max=24.0)


def shapes() -> dict[str, np.ndarray]:
    """Masks of a few shapes on a 64 x 64 image, away from the border."""
    yy, xx = np.mgrid[0:64, 0:64]
    out = {
        'rectangle': (yy >= 20) & (yy < 30) & (xx >= 15) & (xx < 40),
        'ellipse': ((yy - 32) / 9.0) ** 2 + ((xx - 30) / 15.0) ** 2 <= 1.0,
        'triangle': (yy >= 10) & (yy < 50) & (xx >= 10) & (xx - 10 <= (yy - 10) * 0.8),
        'L': ((yy >= 10) & (yy < 40) & (xx >= 10) & (xx < 18)) | ((yy >= 32) & (yy < 40) & (xx >= 10) & (xx < 45)),
    }
    return out


def textured(seed: int) -> np.ndarray:
    """A positive intensity image: a gradient times speckle, in [1, ~300]."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:64, 0:64]
    return (1.0 + 0.2 * xx + 0.1 * yy) * rng.exponential(1.0, (64, 64)) * 4.0 + 0.5


def features_of(img, mask):
    return region_features(img, mask.astype(np.int32), 1, CFG)[0]


@pytest.fixture(params=list(shapes()), ids=str)
def case(request):
    mask = shapes()[request.param]
    return textured(hash(request.param) % 1000), mask


def test_basic_and_contrast_features(case):
    img, mask = case
    f = features_of(img, mask)
    v = img[mask]
    edge = find_boundaries(mask.astype(int), connectivity=1, mode='inner') & mask
    assert f[0] == mask.sum()
    assert f[1] == edge.sum()
    assert f[2] == pytest.approx(v.mean(), rel=1e-12)
    assert f[3] == pytest.approx(v.std(), rel=1e-12)
    assert f[4] == pytest.approx(4 * math.pi * mask.sum() / edge.sum() ** 2, rel=1e-12)
    rows, cols = np.nonzero(mask)
    box = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
    bg = img[box][~mask[box]]
    if bg.size == 0:  # a region filling its rectangle: the one-pixel ring around it
        ring = (slice(rows.min() - 1, rows.max() + 2), slice(cols.min() - 1, cols.max() + 2))
        bg = img[ring][~mask[ring]]
    assert f[5] == pytest.approx(bg.mean(), rel=1e-12)
    i0, b0 = v.mean(), bg.mean()
    assert f[6:9] == pytest.approx([i0 - b0, i0 / b0, (i0 - b0) / (i0 + b0)], rel=1e-12)


def test_shape_moments_of_edge_distances(case):
    img, mask = case
    f = features_of(img, mask)
    rows, cols = np.nonzero(mask)
    cr, cc = rows.mean(), cols.mean()
    er, ec = np.nonzero(find_boundaries(mask.astype(int), connectivity=1, mode='inner') & mask)
    d = np.hypot(er - cr, ec - cc)
    m1 = d.mean()

    def mu(r):
        return np.mean((d - m1) ** r)
    sm1, sm2, sm3 = math.sqrt(mu(2)) / m1, np.cbrt(mu(3)) / m1, mu(4) ** 0.25 / m1
    assert f[9:13] == pytest.approx([sm1, sm2, sm3, sm3 - sm1], rel=1e-9, abs=1e-12)


def test_moment_invariants_match_opencv(case):
    img, mask = case
    f = features_of(img, mask)
    # Eq. (1) takes p along rows (i) and q along columns (j); OpenCV takes x along columns, so it
    # sees our image transposed. M7 changes sign under that reflection, M1-M6 do not.
    hu = cv2.HuMoments(cv2.moments(np.ascontiguousarray((img * mask).T))).ravel()
    assert f[13:20] == pytest.approx(hu, rel=1e-7, abs=1e-18)
    hu_plain = cv2.HuMoments(cv2.moments(img * mask)).ravel()
    assert f[13:19] == pytest.approx(hu_plain[:6], rel=1e-7, abs=1e-18)
    assert f[19] == pytest.approx(-hu_plain[6], rel=1e-7, abs=1e-18)


def test_moment_invariants_are_invariant():
    mask = shapes()['triangle']
    img = textured(3)
    f = features_of(img, mask)
    for k in (1, 2, 3):
        g = features_of(np.rot90(img, k), np.rot90(mask, k))
        assert g[13:20] == pytest.approx(f[13:20], rel=1e-9, abs=1e-18)
    # A shifted copy: all shape and moment features equal (the translation invariance of eq. 1).
    g = features_of(np.roll(img, (5, -3), axis=(0, 1)), np.roll(mask, (5, -3), axis=(0, 1)))
    assert g[9:20] == pytest.approx(f[9:20], rel=1e-9, abs=1e-18)
    # A mirror image: M7 (skew invariant) flips sign, the others stay.
    g = features_of(img[:, ::-1], mask[:, ::-1])
    assert g[13:19] == pytest.approx(f[13:19], rel=1e-9, abs=1e-18)
    assert g[19] == pytest.approx(-f[19], rel=1e-9, abs=1e-18)


def skimage_glcm(levels: np.ndarray, mask: np.ndarray, s: int) -> np.ndarray:
    """Normalised symmetric GLCM of the region over four directions, from scikit-image: pixels
    outside the region get an extra level ``s`` whose row and column are then dropped."""
    lev = np.where(mask, levels, s).astype(np.uint8)
    p = graycomatrix(lev, [1], [0, np.pi / 4, np.pi / 2, 3 * np.pi / 4], levels=s + 1, symmetric=True)
    h = p[:s, :s, 0, :].sum(axis=2).astype(float)
    return h / h.sum()


def test_cooccurrence_features_match_scikit_image(case):
    img, mask = case
    f = features_of(img, mask)
    s = CFG.glcm_levels
    h = skimage_glcm(quantise(img, CFG), mask, s)
    p = h[:, :, None, None]
    assert f[20] == pytest.approx(graycoprops(p, 'contrast')[0, 0], rel=1e-9)
    assert f[21] == pytest.approx(graycoprops(p, 'entropy')[0, 0], rel=1e-9)
    assert f[22] == pytest.approx(graycoprops(p, 'ASM')[0, 0], rel=1e-9)
    assert f[23] == pytest.approx(graycoprops(p, 'homogeneity')[0, 0], rel=1e-9)
    assert f[24] == pytest.approx(graycoprops(p, 'correlation')[0, 0], rel=1e-9)
    assert f[25] == pytest.approx(graycoprops(p, 'variance')[0, 0], rel=1e-9)
    # Sum and difference statistics (no scikit-image property): Haralick's definitions, looped.
    psum = np.zeros(2 * s + 1)  # index k = (i + 1) + (j + 1)
    pdif = np.zeros(s)
    for i in range(s):
        for j in range(s):
            psum[i + j + 2] += h[i, j]
            pdif[abs(i - j)] += h[i, j]
    k = np.arange(2 * s + 1)
    sum_avg = float((k * psum).sum())

    def ent(q):
        return -sum(x * math.log(x) for x in q if x > 0)
    assert f[26] == pytest.approx(sum_avg, rel=1e-9)
    assert f[27] == pytest.approx(ent(psum), rel=1e-9)
    assert f[28] == pytest.approx(float(((k - sum_avg) ** 2 * psum).sum()), rel=1e-9)
    assert f[29] == pytest.approx(ent(pdif), rel=1e-9)


def test_quantisation_is_db_between_the_limits():
    cfg = FeatureConfig(glcm_levels=4, glcm_db_min=0.0, glcm_db_max=20.0)
    db = np.array([-10.0, 0.0, 4.99, 5.0, 12.0, 19.9, 20.0, 40.0])
    assert quantise(10 ** (db / 10), cfg).tolist() == [0, 0, 0, 1, 2, 3, 3, 3]
    assert quantise(np.array([0.0, np.nan]), cfg).tolist() == [0, 0]


def test_many_regions_at_once_equal_one_at_a_time():
    masks = shapes()
    img = textured(7)
    labels = np.zeros(img.shape, np.int32)
    # Non-overlapping: place each shape in its own quadrant of a bigger image.
    big = np.zeros((128, 128))
    big_img = np.ones((128, 128))
    singles = []
    for k, m in enumerate(masks.values()):
        r, c = divmod(k, 2)
        sl = (slice(64 * r, 64 * r + 64), slice(64 * c, 64 * c + 64))
        big[sl] = np.where(m, k + 1, 0)
        big_img[sl] = img
        singles.append(features_of(big_img[sl], m))
    labels = big.astype(np.int32)
    f = region_features(big_img, labels, len(masks), CFG)
    # f06 may differ only where a bounding box reaches into a neighbour quadrant; none does here.
    assert f == pytest.approx(np.array(singles), rel=1e-9, abs=1e-15)


def test_patch_features_equal_the_same_pixels_in_an_image():
    rng = np.random.default_rng(4)
    patches = rng.exponential(2.0, (5, 9, 11)) + 0.1
    masks = patches > 2.0
    masks[3] = False  # an empty window gives NaN
    out = patch_features(patches, masks, CFG)
    assert out.shape == (5, 30) and np.isnan(out[3]).all()
    for k in (0, 1, 2, 4):
        assert out[k] == pytest.approx(features_of(patches[k], masks[k]), rel=1e-9, abs=1e-15)


def test_a_subset_is_the_same_columns_computed_alone():
    rng = np.random.default_rng(8)
    patches = rng.exponential(2.0, (20, 9, 9)) + 0.1
    masks = patches > 1.5
    full = patch_features(patches, masks, CFG)
    for subset in [PAPER_FEATURES, (1,), (3, 6), (13, 12, 11, 10), (30, 21), tuple(range(30, 0, -1))]:
        part = patch_features(patches, masks, CFG, features=subset)
        assert part.shape == (20, len(subset))
        assert part == pytest.approx(full[:, [f - 1 for f in subset]], rel=1e-12, nan_ok=True)
    with pytest.raises(ValueError, match='1..30'):
        patch_features(patches, masks, CFG, features=(0, 3))


def test_special_cases_single_pixel_border_and_no_background():
    img = np.full((8, 8), 2.0)
    img[3, 4] = 50.0
    one = np.zeros((8, 8), bool)
    one[3, 4] = True
    f = features_of(img, one)
    assert f[0] == 1 and f[1] == 1 and f[2] == 50.0 and f[3] == 0.0
    # The rectangle holds only the pixel: the one-pixel ring around it is the background.
    assert f[5] == 2.0
    assert f[9:13].tolist() == [0.0, 0.0, 0.0, 0.0]
    # GLCM of one pixel: paired with itself, so a single cell of probability 1.
    assert f[22] == 1.0 and f[21] == 0.0 and f[20] == 0.0
    # A region on the image border: the border counts as its edge (no neighbour inside).
    edge = np.zeros((8, 8), bool)
    edge[0, :] = True
    assert features_of(img, edge)[1] == 8
    # No-data pixels (0 or NaN) are never background.
    img2 = img.copy()
    img2[2:5, 3:6] = 0.0
    img2[2, 3] = np.nan
    img2[3, 4] = 50.0
    img2[4, 5] = 6.0
    block = np.zeros((8, 8), bool)
    block[3, 4] = block[4, 4] = True
    img2[4, 4] = 10.0
    # The ring rows 2-5, cols 3-5 holds data only at (4, 5) = 6 and row 5 = 2, 2, 2.
    assert features_of(img2, block)[5] == pytest.approx((6.0 + 3 * 2.0) / 4)


def test_table_numbering_and_paper_subset():
    assert len(FEATURE_LABELS) == 30
    assert [FEATURE_LABELS[f - 1] for f in PAPER_FEATURES] == ['M7', 'M4', 'mean intensity', 'background mean',
                                                               'GLCM IDM']


def test_bad_inputs_and_settings():
    with pytest.raises(ValueError, match='one shape'):
        region_features(np.ones((4, 4)), np.ones((4, 5), np.int32))
    with pytest.raises(ValueError, match='labels go up to 2 but n = 1'):
        region_features(np.ones((4, 4)), np.full((4, 4), 2, np.int32), 1)
    with pytest.raises(ConfigError, match='glcm_db_max'):
        FeatureConfig(glcm_db_min=10.0, glcm_db_max=5.0)
    with pytest.raises(ConfigError, match='glcm_levels'):
        FeatureConfig(glcm_levels=1)
    assert region_features(np.ones((4, 4)), np.zeros((4, 4), np.int32)).shape == (0, 30)

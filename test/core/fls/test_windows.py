"""Window features (the GPF tracker's particle-rate path) equal the general Table 2 computation of
patch_features on the same pixels: every feature, at the border, outside the image, without data."""
from __future__ import annotations

import numpy as np
import pytest

from sonar_tracking.core.fls import FeatureConfig, patch_features
from sonar_tracking.core.fls.features import glcm_features
from sonar_tracking.core.fls.windows import WindowImage, window_features


def image(seed: int, shape=(90, 70)) -> np.ndarray:
    """Speckled background with bright targets, a no-data strip and a NaN."""
    rng = np.random.default_rng(seed)
    img = rng.exponential(1.0, shape) * np.where(rng.random(shape) < 0.05, 40.0, 1.0)
    img[30:36, 20:31] *= 25.0
    img[:, :6] = 0.0
    img[5, 50] = np.nan
    return img.astype(np.float32)


def reference(wi: WindowImage, rows, cols, size, config, features=None):
    p = wi.patches(rows, cols, size)
    m = np.zeros(p.shape, bool)
    m[:, 1:-1, 1:-1] = True
    return patch_features(p, m, config, features)


def close(got, ref):
    # Relative to each feature's magnitude over the windows (Hu invariants of near-symmetric
    # windows are differences of nearly equal terms).
    scale = np.nanmax(np.abs(ref), axis=0, keepdims=True) + 1e-300
    np.testing.assert_allclose(got / scale, ref / scale, rtol=0, atol=1e-9)


@pytest.mark.parametrize('size', [3, 7, 11])
@pytest.mark.parametrize('levels,distance', [(8, 1), (16, 2), (5, 3), (32, 1)])
def test_all_features_equal_the_general_path(size, levels, distance):
    cfg = FeatureConfig(glcm_levels=levels, glcm_distance=distance, glcm_db_max=20.0)
    img = image(size + levels)
    rng = np.random.default_rng(levels)
    rows = rng.integers(-15, img.shape[0] + 15, 120)   # some outside, some on the border
    cols = rng.integers(-15, img.shape[1] + 15, 120)
    wi = WindowImage(img, cfg)
    got = wi.features(rows, cols, size)
    close(got, reference(wi, rows, cols, size, cfg))
    assert np.isfinite(got).all()


def test_subsets_and_order_and_the_one_call_form():
    cfg = FeatureConfig()
    img = image(3)
    rows, cols = np.array([33, 10, 0, 89]), np.array([25, 40, 69, 3])
    wi = WindowImage(img, cfg)
    full = wi.features(rows, cols, 11)
    for subset in [(20, 17, 3, 6, 24), (24,), (6, 3), (1, 2, 5, 10, 13), (21, 30, 22)]:
        sub = wi.features(rows, cols, 11, subset)
        np.testing.assert_array_equal(sub, full[:, [f - 1 for f in subset]])
        np.testing.assert_array_equal(window_features(img, rows, cols, 11, cfg, subset), sub)


def test_windows_without_any_data_take_the_core_fallbacks():
    cfg = FeatureConfig()
    img = image(4)
    rows = np.array([-40, 500, 33])          # two far outside, one on a target
    cols = np.array([-40, 500, 25])
    wi = WindowImage(img, cfg)
    got = wi.features(rows, cols, 9)
    close(got, reference(wi, rows, cols, 9, cfg))
    assert got[0, 2] == 0.0 and got[1, 2] == 0.0          # f03: no data is intensity 0
    zero = WindowImage(np.zeros((20, 20)), cfg).features(np.array([10]), np.array([10]), 5)
    assert np.isfinite(zero).all() and zero[0, 5] == 1.0   # f06 of an empty image: the core's 1.0


def test_a_window_of_one_grey_level_pairs_without_partners():
    """A distance longer than the window leaves no pixel pair: the core's one-pixel rule."""
    cfg = FeatureConfig(glcm_distance=5)
    img = image(5)
    wi = WindowImage(img, cfg)
    rows, cols = np.array([33, 60]), np.array([25, 30])
    close(wi.features(rows, cols, 3), reference(wi, rows, cols, 3, cfg))


def test_bad_arguments_say_what_to_fix():
    wi = WindowImage(np.ones((10, 10)), max_size=9)
    with pytest.raises(ValueError, match='odd integer'):
        wi.features(np.array([1]), np.array([1]), 4)
    with pytest.raises(ValueError, match='max_size'):
        wi.features(np.array([1]), np.array([1]), 11)
    with pytest.raises(ValueError, match='integer pixel'):
        wi.features(np.array([1.5]), np.array([1.0]), 5)
    with pytest.raises(ValueError, match='2-D'):
        WindowImage(np.ones(5))
    with pytest.raises(ValueError, match='21..30'):
        glcm_features(np.ones((1, 4, 4)), [20])
    assert wi.features(np.zeros(0, int), np.zeros(0, int), 5, (3, 24)).shape == (0, 2)


def test_glcm_subset_equals_the_full_statistics():
    rng = np.random.default_rng(9)
    h = rng.integers(0, 9, (6, 8, 8)).astype(float)
    h = h + h.transpose(0, 2, 1)
    full = glcm_features(h)
    for subset in [(24,), (30, 21), (25, 26, 27, 28, 29)]:
        np.testing.assert_array_equal(glcm_features(h, subset), full[:, [f - 21 for f in subset]])

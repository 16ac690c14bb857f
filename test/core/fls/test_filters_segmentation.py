"""The modified median filter (trimmed mean in resolution cells, range-normalised) and the modified
region growing, on synthetic data with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.background import range_profile as background_level
from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.fls import (
    FilterConfig,
    ImageGrid,
    PolarSweepFilter,
    SegmentConfig,
    cells_per_pixel,
    grow_regions,
    median_blur,
    threshold_components,
    trimmed_mean,
)
from sonar_tracking.core.sector import SectorGeometry


def brute_trimmed(v: np.ndarray, wb: int, ww: int, trim: int) -> np.ndarray:
    """Per-cell loop: sort the valid samples of the window, drop ``trim`` at each end, average."""
    out = np.full(v.shape, np.nan)
    for i in range(v.shape[0]):
        for j in range(v.shape[1]):
            w = v[max(0, i - wb // 2):i + wb // 2 + 1, max(0, j - ww // 2):j + ww // 2 + 1].ravel()
            w = np.sort(w[np.isfinite(w)])
            if w.size == 0:
                continue
            if w.size < 2 * trim + 1:
                out[i, j] = np.median(w)
            else:
                out[i, j] = w[trim:w.size - trim].mean()
    return out


@pytest.mark.parametrize('window, trim', [((3, 3), 0), ((3, 3), 1), ((3, 3), 2), ((3, 3), 4), ((5, 3), 0),
                                          ((5, 3), 1), ((5, 3), 4), ((1, 3), 0), ((1, 3), 1)])
def test_trimmed_mean_against_a_loop(window, trim):
    rng = np.random.default_rng(trim * 10 + window[0])
    v = rng.exponential(1.0, (14, 9)).astype(np.float32)
    v[rng.random(v.shape) < 0.15] = np.nan
    got = trimmed_mean(v, window[0], window[1], trim)
    want = brute_trimmed(v.astype(np.float64), window[0], window[1], trim)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    assert np.allclose(got[~np.isnan(got)], want[~np.isnan(want)], rtol=1e-5)


def test_trim_of_half_the_window_is_the_median_and_a_spike_is_removed():
    rng = np.random.default_rng(1)
    v = rng.exponential(1.0, (20, 20)).astype(np.float32)
    from scipy.ndimage import median_filter
    inner = (slice(1, -1), slice(1, -1))
    assert np.allclose(trimmed_mean(v, 3, 3, 4)[inner], median_filter(v, 3)[inner])
    v[10, 10] = 1000.0  # one impulsive cell
    assert trimmed_mean(v, 3, 3, 1)[9:12, 9:12].max() < 5.0
    assert trimmed_mean(v, 3, 3, 0)[9:12, 9:12].min() > 100.0


def test_background_level_is_the_mean_of_exponential_speckle_at_each_range():
    rng = np.random.default_rng(2)
    profile = np.linspace(1.0, 10.0, 400) ** 2  # intensity growing with range
    raw = rng.exponential(1.0, (400, 100)) * profile[:, None]
    raw[200:204, 50:53] *= 100.0  # a target does not move the median
    ratio = background_level(raw, 41) / profile
    assert np.abs(ratio[30:-30] - 1.0).max() < 0.1 and abs(ratio.mean() - 1.0) < 0.03


def sweep(n_sectors=10, beams=10, bins=60, seed=3):
    rng = np.random.default_rng(seed)
    full = rng.exponential(1.0, (bins, n_sectors * beams)).astype(np.float32)
    inc = math.radians(0.9)
    out = []
    for k in range(n_sectors):
        g = SectorGeometry(angle_min=-0.7 + k * beams * inc, angle_increment=inc, n_beams=beams, range_min=0.5,
                           range_max=30.0, n_bins=bins, ping_period=0.05, scan_time=5.0)
        out.append((full[:, k * beams:(k + 1) * beams], g))
    return full, out


def test_sector_by_sector_filtering_equals_filtering_the_whole_sweep():
    full, sectors = sweep()
    cfg = FilterConfig(window_bins=3, window_beams=5, trim=1, normalise=False)
    f = PolarSweepFilter(cfg)
    latest = np.full(full.shape, np.nan, np.float32)
    inc = sectors[0][1].angle_increment
    for a, g in sectors:
        for block in f.add(a, g):
            cols = np.rint((block.geometry.bearings() + 0.7) / inc).astype(int)
            latest[:, cols] = block.values
    want = trimmed_mean(full, 3, 5, 1)
    # Every beam but the last two is final: they were filtered again once their neighbours came.
    assert np.allclose(latest[:, :-2], want[:, :-2], rtol=1e-5)


def test_only_this_and_the_previous_sector_are_painted():
    """Beams of an earlier pass next to a new sector are not painted again: on a moving platform
    they were taken elsewhere, and their pixels belong to that time."""
    _, sectors = sweep()
    f = PolarSweepFilter(FilterConfig())
    for a, g in sectors:  # first pass at x = 0
        f.add(a, g, (0.0, 0.0, 0.0))
    poses = set()
    for k, (a, g) in enumerate(reversed(sectors[3:6])):  # back over them, 10 m on
        blocks = f.add(a, g, (10.0 + k, 0.0, 0.0))
        poses |= {b.pose for b in blocks}
        # Only this sector's beams, and the edge beam of the one before it.
        assert sum(b.geometry.n_beams for b in blocks) <= g.n_beams + 1
    # The first pass (at x = 0) is never painted again.
    assert poses == {(10.0, 0.0, 0.0), (11.0, 0.0, 0.0), (12.0, 0.0, 0.0)}


def test_filter_normalises_by_range_and_restarts_on_a_new_geometry():
    full, sectors = sweep(bins=200)
    f = PolarSweepFilter(FilterConfig())
    ramp = np.linspace(1.0, 30.0, 200)[:, None].astype(np.float32)
    out = []
    for a, g in sectors:
        out += [b.values for b in f.add(a * ramp, g)]
    out = np.concatenate(out, axis=1)
    # Normalised: the background mean is about 1 at every range despite the 30x ramp.
    assert 0.85 < np.nanmean(out[:20]) < 1.15 and 0.85 < np.nanmean(out[-20:]) < 1.15
    other = SectorGeometry(angle_min=0.0, angle_increment=0.02, n_beams=5, range_min=1.0, range_max=10.0, n_bins=50)
    blocks = f.add(np.ones((50, 5), np.float32), other)
    assert sum(b.geometry.n_beams for b in blocks) == 5


def test_filter_settings_refused_with_reasons():
    with pytest.raises(ConfigError, match='window_bins = 4 must be odd'):
        FilterConfig(window_bins=4)
    with pytest.raises(ConfigError, match='use at most 4'):
        FilterConfig(trim=5)


def blob_image(shape=(80, 80)):
    rng = np.random.default_rng(5)
    return (rng.uniform(0.4, 0.6, shape)).astype(np.float32)  # well below the growth level (3 dB)


def add_blob(img, r, c, peak, sigma=1.5):
    yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    img += peak * np.exp(-((yy - r) ** 2 + (xx - c) ** 2) / (2 * sigma ** 2))
    return img


def test_region_grows_from_a_seed_over_weaker_pixels_only_when_seeded():
    img = add_blob(blob_image(), 20, 20, 20.0)
    img = add_blob(img, 60, 60, 2.5)  # above grow (3 dB = 2.0) but never above the seed level
    labels, n = grow_regions(img, SegmentConfig(min_cells=1), 0.1)
    assert n == 1 and labels[20, 20] == 1 and labels[60, 60] == 0
    # The region reaches down to the growth level, not just the seed level.
    assert (img[labels == 1] < 10 ** 0.55).any() and (img[labels == 1] > 2.0).all()


def test_fragments_within_the_join_distance_become_one_region():
    img = blob_image()
    for c in (30, 35):  # two spots 0.5 m apart at 0.1 m pixels, separated by background
        add_blob(img, 40, c, 20.0, sigma=0.8)
    assert grow_regions(img, SegmentConfig(min_cells=1, join_distance=0.0), 0.1)[1] == 2
    labels, n = grow_regions(img, SegmentConfig(min_cells=1, join_distance=0.6), 0.1)
    assert n == 1 and labels[40, 30] == labels[40, 35] == 1
    # Joining does not add the gap pixels to the region.
    assert labels[40, 32] == 0 or img[40, 32] > 2.0
    assert threshold_components(img, 10 ** 0.55)[1] == 2


def test_growth_tolerance_keeps_a_strong_region_to_its_main_lobe():
    img = add_blob(blob_image(), 40, 40, 1000.0, sigma=3.0)
    wide = (grow_regions(img, SegmentConfig(min_cells=1, tolerance_db=60.0), 0.1)[0] > 0).sum()
    tight = (grow_regions(img, SegmentConfig(min_cells=1, tolerance_db=10.0), 0.1)[0] > 0).sum()
    assert tight < 0.5 * wide
    # Within 10 dB of the 30 dB peak: the radius where the Gaussian blob falls by 10 dB.
    assert tight == pytest.approx(math.pi * (3.0 * math.sqrt(2 * math.log(10))) ** 2, rel=0.2)


def test_area_is_counted_in_resolution_cells():
    grid = ImageGrid(resolution=0.1, width=300, height=300, origin_x=0.0, origin_y=-15.0)
    w = cells_per_pixel(grid, (0.0, 0.0, 0.0), math.radians(0.9), 0.05)
    x, y = grid.pixel_to_point(150, 100)  # 10 m out
    assert w[150, 100] == pytest.approx(0.01 / (math.hypot(x, y) * math.radians(0.9) * 0.05), rel=1e-6)
    img = np.zeros(grid.shape, np.float32) + 0.5
    img[148:152, 48:52] = 20.0    # 16 pixels at about 5 m: many cells per pixel
    img[148:152, 248:252] = 20.0  # 16 pixels at about 25 m: under one cell per pixel
    labels, n = grow_regions(img, SegmentConfig(min_cells=16.0, join_distance=0.0), 0.1, w)
    assert n == 1 and labels[150, 50] == 1
    assert grow_regions(img, SegmentConfig(min_cells=16.0, join_distance=0.0), 0.1)[1] == 2


def test_max_area_and_max_regions():
    img = np.full((60, 60), 20.0, np.float32)
    assert grow_regions(img, SegmentConfig(max_area=1.0), 0.1)[1] == 0
    spots = blob_image()
    for k in range(5):
        add_blob(spots, 10 + 14 * k, 40, 5.0 * (k + 1), sigma=1.0)
    labels, n = grow_regions(spots, SegmentConfig(min_cells=1, max_regions=2), 0.1)
    assert n == 2 and labels[66, 40] > 0 and labels[52, 40] > 0


def test_segment_settings_refused_with_reasons():
    with pytest.raises(ConfigError, match='grow_db = 6.0 must not exceed seed_db = 5.0'):
        SegmentConfig(seed_db=5.0, grow_db=6.0)
    with pytest.raises(ConfigError, match='max_area'):
        SegmentConfig(max_area=0.0)


def test_plain_median_blur_baseline():
    img = np.zeros((9, 9), np.float32)
    img[4, 4] = 100.0
    img[0, 0] = np.nan
    assert median_blur(img, 3).max() == 0.0
    assert median_blur(img, 7).shape == img.shape
    with pytest.raises(ValueError, match='odd'):
        median_blur(img, 4)

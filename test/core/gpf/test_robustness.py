"""Inputs that once crashed the GPF tracker or made it refuse every frame, and tracks that leave
the sensor's coverage."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from sonar_tracking.core.fls import ImageGrid
from sonar_tracking.core.fls.windows import WindowImage
from sonar_tracking.core.gpf import GpfConfig, GpfInputError, GpfTracker
from sonar_tracking.core.gpf.cues import MAX_WINDOW, coarsen, coarsening
from sonar_tracking.core.gpf.tracker import check_image
from sonar_tracking.core.records import REGION_DTYPE


@pytest.mark.parametrize('size', [3, 9, 31])
def test_window_patches_at_and_beyond_every_edge_read_the_right_pixels(size):
    # Regression: a particle just outside the image (within a window of its edge) indexed one past
    # the padded image's end (IndexError) or wrapped into the next row's pixels.
    rng = np.random.default_rng(size)
    img = rng.random((23, 17)) + 0.5
    wi = WindowImage(img, max_size=size)
    half = size // 2 + 1
    big = np.pad(img, 3 * size)              # zero (no data) outside the image
    rows, cols = np.meshgrid(np.arange(-2 * size, 23 + 2 * size), np.arange(-2 * size, 17 + 2 * size),
                             indexing='ij')
    rows, cols = rows.ravel(), cols.ravel()
    got = wi.patches(rows, cols, size)
    for k, (r, c) in enumerate(zip(rows, cols)):
        want = big[r + 3 * size - half:r + 3 * size + half + 1, c + 3 * size - half:c + 3 * size + half + 1]
        np.testing.assert_array_equal(got[k], want)
    assert np.isfinite(wi.features(rows, cols, size, (3, 6, 17, 20, 24))).all()


def scene(grid: ImageGrid, rng, targets, fan_end: float | None = None) -> np.ndarray:
    """Speckle near 1 with 0.3 x 0.9 m echoes at ``targets``; pixels beyond x = ``fan_end`` hold no
    data (0), as outside a sonar's fan."""
    rows, cols = np.indices(grid.shape)
    img = rng.gamma(16.0, 1.0 / 16.0, grid.shape)
    s = 0.1 / grid.resolution
    for x, y in targets:
        r, c = grid.point_to_pixel(x, y)
        img += 12.0 * np.exp(-0.5 * (((cols - c) / (1.5 * s)) ** 2 + ((rows - r) / (4.0 * s)) ** 2))
    if fan_end is not None:
        x, _ = grid.pixel_to_point(rows, cols)
        img[x > fan_end] = 0.0
    return img.astype(np.float32)


def regions(*points) -> np.ndarray:
    rec = np.zeros(len(points), REGION_DTYPE)
    for i, (x, y) in enumerate(points):
        rec[i]['region_id'], rec[i]['x'], rec[i]['y'] = i + 1, x, y
    return rec


@pytest.mark.parametrize('resolution,pixel,window,capped', [
    (0.025, 0.0, 29, False), (0.02, 0.0, 35, False), (0.005, 0.0, MAX_WINDOW, True),
    (0.025, 0.1, 7, False), (0.02, 0.1, 7, False), (0.03, 0.1, 7, False)])
def test_fine_images_track_up_to_and_beyond_the_edge_without_failing(resolution, pixel, window, capped):
    # Regressions: on its own 0.025 m pixels the 29-pixel window of a particle at the image's edge
    # indexed past the padded image (IndexError); on 0.02 m pixels (35, more than the 31 the window
    # image was built for) every frame failed. On 0.005 m pixels the window is capped at MAX_WINDOW
    # pixels, and says so. By default (cues.pixel 0.1 m) fine images are block-averaged to about
    # 0.1 m, where the window has 7 pixels.
    grid = ImageGrid(resolution=resolution, width=int(round(4.0 / resolution)), height=int(round(3.0 / resolution)),
                     origin_x=0.0, origin_y=-1.5)
    rng = np.random.default_rng(1)
    tracker = GpfTracker(GpfConfig.from_flat({'particles': 100, 'cues.pixel': pixel}), np.random.default_rng(2))
    for k in range(8):
        p = (1.0 + 0.4 * k, 0.0)                # leaves the image (x up to 4 m) at frame 8
        tracker.step(5.0 * k, scene(grid, rng, [p]), grid, regions(p), (0.0, 0.0, 0.0))
        for tr in tracker.tracks:
            assert np.isfinite(tr.mean).all() and np.isfinite(tr.cov).all()
        if k <= 5:
            assert len(tracker.tracks) == 1 and np.hypot(*(tracker.tracks[0].mean[:2] - p)) < 0.5
    assert tracker.report.window_pixels == window and tracker.report.window_capped == capped
    assert tracker.report.cue_pixel == pytest.approx(resolution * coarsening(pixel, resolution))


def test_coarsening_averages_the_pixels_with_data():
    grid = ImageGrid(resolution=0.05, width=5, height=3, origin_x=1.0, origin_y=2.0, origin_yaw=0.3)
    img = np.arange(15.0).reshape(3, 5)
    img[0, 0] = 0.0
    out, coarse = coarsen(img, img > 0, grid, 2)
    np.testing.assert_allclose(out, [[(1 + 5 + 6) / 3, (2 + 3 + 7 + 8) / 4, (4 + 9) / 2], [(10 + 11) / 2, 12.5, 14.0]])
    assert (coarse.width, coarse.height, coarse.resolution) == (3, 2, 0.1)
    np.testing.assert_allclose(coarse.pixel_to_point(0, 0), grid.pixel_to_point(0.5, 0.5))
    assert [coarsening(0.1, r) for r in (0.1, 0.07, 0.05, 0.0333, 0.2)] == [1, 1, 2, 3, 1]
    assert coarsening(0.0, 0.01) == 1


def test_round_off_negatives_read_as_zero_and_real_negatives_are_refused():
    grid = ImageGrid(resolution=0.1, width=60, height=40, origin_x=0.0, origin_y=-2.0)
    img = scene(grid, np.random.default_rng(3), [(3.0, 0.0)]).astype(np.float64)
    img[:, :5] = 0.0
    img[0, :5] = -1.5e-15                       # a filter's round-off next to intensities near 1
    tracker = GpfTracker(rng=np.random.default_rng(4))
    tracker.step(0.0, img, grid, regions((3.0, 0.0)))
    assert len(tracker.tracks) == 1
    assert (check_image(img, grid) >= 0).all() and (img[0, :5] < 0).all()   # the caller's array is kept
    img[0, 0] = -0.5
    with pytest.raises(GpfInputError, match='5 negative pixels down to -0.5'):
        tracker.step(5.0, img, grid, regions((3.0, 0.0)))


def test_a_track_ends_after_its_estimate_leaves_the_sonar_coverage():
    # The target crosses the fan's far edge (no data beyond x = 8 m) and the track would coast for
    # lost.max_time (60 s); it ends once its estimate has been outside the data for outside_time.
    grid = ImageGrid(resolution=0.1, width=120, height=60, origin_x=0.0, origin_y=-3.0)

    def walk(k):
        return (4.0 + 0.5 * k, 0.2)

    def run(config, frames):
        tracker = GpfTracker(GpfConfig.from_flat({'lost.max_time': 60.0, **config}), np.random.default_rng(6))
        alive = []
        for k, (img, reg) in enumerate(frames):
            tracker.step(5.0 * k, img, grid, reg, (0.0, 0.0, 0.0))
            alive.append((len(tracker.tracks), tracker.report.outside))
        return alive

    rng = np.random.default_rng(5)
    frames = [(scene(grid, rng, [walk(k)], 8.0), regions(walk(k)) if walk(k)[0] < 8.0 else regions())
              for k in range(16)]
    alive = run({}, frames)
    assert alive[6] == (1, 0)                   # x 7 m: still inside
    first = next(k for k, (_, out) in enumerate(alive) if out)
    # outside_time 2 s < one 5 s frame: ends at the second frame outside, long before max_time.
    assert alive[first] == (1, 1) and alive[first + 1][0] == 0 and first <= 12
    assert run({'lost.outside_time': 12.0}, frames)[first + 2][0] == 1
    assert run({'lost.outside_time': 12.0}, frames)[first + 3][0] == 0
    # A frame without any data (a dropout) neither starts nor stops the clock.
    frames[first] = (np.zeros(grid.shape, np.float32), regions())
    alive = run({}, frames)
    assert alive[first] == (1, 0) and alive[first + 1] == (1, 1) and alive[first + 2][0] == 0


def test_updating_tracks_together_equals_updating_them_one_by_one():
    # Three tracks, one with its cloud half outside the fan (windows without data take the f06
    # fallback, the median of that cloud's own windows): the batched update draws the same numbers
    # and gives bit-identical posteriors.
    grid = ImageGrid(resolution=0.1, width=120, height=80, origin_x=0.0, origin_y=-4.0)
    rng = np.random.default_rng(7)
    pts = [(3.0, -2.0), (6.0, 1.5), (9.2, 0.0)]
    frames = [(scene(grid, rng, pts, 9.5), regions(*pts)) for _ in range(4)]
    base = GpfTracker(rng=np.random.default_rng(8))
    for k, (img, reg) in enumerate(frames[:3]):
        base.step(5.0 * k, img, grid, reg, (0.0, 0.0, 0.0))
    assert len(base.tracks) == 3
    frame = base.prepare(frames[3][0], grid)
    together, alone = copy.deepcopy(base), copy.deepcopy(base)
    together.update_tracks(together.tracks, frame, [None] * 3)
    for tr in alone.tracks:
        alone.update_track(tr, frame)
    for a, b in zip(together.tracks, alone.tracks):
        np.testing.assert_array_equal(a.mean, b.mean)
        np.testing.assert_array_equal(a.cov, b.cov)
        np.testing.assert_array_equal(a.last_weights, b.last_weights)
    assert together.rng.random() == alone.rng.random()

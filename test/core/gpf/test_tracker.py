"""The GPF tracker on synthetic frames: tracking, weights always normalised and finite, an empty image
or a frame without regions does not lose a healthy track, lost tracks end, births, restarts, bad
input, determinism; the SIR and EKF baselines; settings. Inputs that once crashed it or made it
refuse every frame (windows at the image's edge, fine images, round-off negatives); tracks that
leave the sonar's coverage; the batched update equals updating the tracks one by one."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.fls import ImageGrid
from sonar_tracking.core.fls.windows import WindowImage
from sonar_tracking.core.gpf import EkfTracker, GpfConfig, GpfInputError, GpfTracker
from sonar_tracking.core.gpf.cues import MAX_WINDOW, coarsen, coarsening
from sonar_tracking.core.gpf.tracker import check_image
from sonar_tracking.core.records import GPF_TRACK_DTYPE, REGION_DTYPE
from sonar_tracking.core.timeline import TimeWentBack

GRID = ImageGrid(resolution=0.1, width=220, height=160, origin_x=0.0, origin_y=-8.0)


def scene(grid: ImageGrid, rng, targets, fan_end: float | None = None, amplitude=12.0) -> np.ndarray:
    """Background near 1 (speckle after filtering) and 0.3 x 0.9 m echoes at ``targets``; pixels
    beyond x = ``fan_end`` hold no data (0), as outside a sonar's fan."""
    rows, cols = np.indices(grid.shape)
    img = rng.gamma(16.0, 1.0 / 16.0, grid.shape)
    s = 0.1 / grid.resolution
    for x, y in targets:
        r, c = grid.point_to_pixel(x, y)
        img += amplitude * np.exp(-0.5 * (((cols - c) / (1.5 * s)) ** 2 + ((rows - r) / (4.0 * s)) ** 2))
    if fan_end is not None:
        x, _ = grid.pixel_to_point(rows, cols)
        img[x > fan_end] = 0.0
    return img.astype(np.float32)


def image(rng, *targets, amplitude=12.0) -> np.ndarray:
    """:func:`scene` on GRID."""
    return scene(GRID, rng, targets, amplitude=amplitude)


def regions(*points) -> np.ndarray:
    rec = np.zeros(len(points), REGION_DTYPE)
    for i, (x, y) in enumerate(points):
        rec[i]['region_id'], rec[i]['x'], rec[i]['y'] = i + 1, x, y
    return rec


def walk(k: int, y0: float = 0.5, vx: float = 0.25) -> tuple[float, float]:
    """A target towed along x at ``vx`` m/s with a small wobble, frames 5 s apart."""
    return 6.0 + 5.0 * vx * k, y0 + 0.15 * math.sin(0.9 * k)


def run(tracker, frames, check=None):
    out = []
    for k, (img, reg) in enumerate(frames):
        out.append(tracker.step(5.0 * k, img, GRID, reg, (0.0, 0.0, 0.0)))
        if check:
            check(tracker)
    return out


def check_weights(tracker):
    for tr in tracker.tracks:
        if tr.last_weights is not None:
            w = tr.last_weights
            assert np.isfinite(w).all() and (w >= 0).all() and abs(w.sum() - 1.0) < 1e-9
        assert np.isfinite(tr.mean).all() and np.isfinite(tr.cov).all()
        assert np.all(np.linalg.eigvalsh(tr.cov) > 0)


@pytest.mark.parametrize('mode', ['af', 'mf', 'wf'])
def test_follows_a_towed_target_with_normalised_finite_weights(mode):
    rng = np.random.default_rng(1)
    frames = [(image(rng, walk(k)), regions(walk(k))) for k in range(13)]     # x 6 to 21 m; the image ends at 22 m
    tracker = GpfTracker(GpfConfig.from_flat({'fusion.mode': mode}), np.random.default_rng(2))
    recs = run(tracker, frames, check_weights)
    assert all(r.dtype == GPF_TRACK_DTYPE for r in recs)
    assert len(recs[-1]) == 1 and recs[-1]['confirmed'][0] == 1 and recs[-1]['track_id'][0] == 1
    err = [math.hypot(r['x'][0] - walk(k)[0], r['y'][0] - walk(k)[1]) for k, r in enumerate(recs)]
    assert max(err) < 0.5 and np.mean(err[3:]) < 0.2, err
    assert abs(recs[-1]['vx'][0] - 0.25) < 0.1
    assert tracker.report.seen == 1 and set(recs[-1]['fusion']) <= {0, 1}
    if mode != 'af':
        assert (recs[-1]['fusion'] == (0 if mode == 'mf' else 1)).all()


def test_weights_stay_normalised_and_finite_on_hostile_images():
    rng = np.random.default_rng(3)
    # Six frames (30 s) that may all miss the target: the lost time must outlast them.
    tracker = GpfTracker(GpfConfig.from_flat({'lost.max_time': 60.0}), np.random.default_rng(4))
    run(tracker, [(image(rng, walk(k)), regions(walk(k))) for k in range(3)])
    hostile = [image(rng, walk(3)) * 1e30, np.full(GRID.shape, 1.0, np.float32), image(rng, walk(5), amplitude=1e-3),
               np.where(rng.random(GRID.shape) < 0.5, np.nan, image(rng, walk(6))).astype(np.float32),
               np.full(GRID.shape, np.inf, np.float32), image(rng, walk(8))]
    for k, img in enumerate(hostile, start=3):
        tracker.step(5.0 * k, img, GRID, regions(), None)
        check_weights(tracker)
        assert len(tracker.tracks) == 1


def test_an_empty_image_and_a_frame_without_regions_do_not_lose_a_healthy_track():
    rng = np.random.default_rng(5)
    frames = [(image(rng, walk(k)), regions(walk(k))) for k in range(6)]
    frames.append((np.zeros(GRID.shape, np.float32), regions()))     # no data at all
    frames.append((image(rng, walk(7)), regions()))                  # echo, no region
    frames.append((image(rng), regions()))                           # target faded: no echo, no region
    frames += [(image(rng, walk(k)), regions(walk(k))) for k in range(9, 12)]
    tracker = GpfTracker(rng=np.random.default_rng(6))
    recs = run(tracker, frames, check_weights)
    ids = [r['track_id'].tolist() for r in recs[1:]]
    assert all(i == [1] for i in ids), ids
    assert all(r['confirmed'][0] == 1 for r in recs[1:])
    for k in (6, 7, 8, 9, 11):
        r = recs[k][0]
        assert math.hypot(r['x'] - walk(k)[0], r['y'] - walk(k)[1]) < 0.8, (k, r)
    assert recs[6]['cov_xx'][0] > recs[5]['cov_xx'][0]               # step 3: widened while unseen


def test_a_lost_track_ends_after_the_lost_time_and_tentative_ones_sooner():
    rng = np.random.default_rng(7)
    tracker = GpfTracker(GpfConfig.from_flat({'lost.max_time': 12.0}), np.random.default_rng(8))
    run(tracker, [(image(rng, walk(k)), regions(walk(k))) for k in range(4)])
    stamps, alive = [], []
    for k in range(4, 9):
        tracker.step(5.0 * k, image(rng), GRID, regions(), None)
        stamps.append(5.0 * k)
        alive.append(len(tracker.tracks))
    assert alive == [1, 1, 0, 0, 0]                                 # last seen at 15 s: ends once > 12 s
    tracker.step(45.0, image(rng, (12.0, -5.0)), GRID, regions((12.0, -5.0)), None)
    assert len(tracker.tracks) == 1 and not tracker.tracks[0].confirmed and tracker.tracks[0].track_id == 2
    tracker.step(50.0, image(rng), GRID, regions(), None)
    tracker.step(55.0, image(rng), GRID, regions(), None)
    assert tracker.tracks == []                                      # tentative: ends after 6 s


def test_births_from_unexplained_regions_only():
    rng = np.random.default_rng(9)
    a, b = (10.0, 1.25), (10.0, -1.25)                              # side by side, 2.5 m apart
    tracker = GpfTracker(rng=np.random.default_rng(10))
    tracker.step(0.0, image(rng, a, b), GRID, regions(a, b, (10.3, 1.3)), (0.0, 0.0, 0.0))
    assert [tr.track_id for tr in tracker.tracks] == [1, 2]         # the fragment 0.3 m off joins its target
    tracker.step(5.0, image(rng, a, b), GRID, regions(a, b), (0.0, 0.0, 0.0))
    assert len(tracker.tracks) == 2 and all(tr.confirmed for tr in tracker.tracks)
    # The initial spread lies along the line of sight from the sonar (range 0.63 m, across 0.67 m).
    cov = GpfTracker(rng=np.random.default_rng(0))
    cov.step(0.0, image(rng, (0.0, 10.0)), GRID, regions((0.0, 10.0)), (0.0, 0.0, 0.0))
    c = cov.tracks[0].cov
    assert c[0, 0] == pytest.approx(0.45, rel=1e-3) and c[1, 1] == pytest.approx(0.40, rel=1e-3)


def test_a_lost_track_takes_up_its_region_again_with_its_id():
    rng = np.random.default_rng(11)
    tracker = GpfTracker(rng=np.random.default_rng(12))
    run(tracker, [(image(rng, walk(k)), regions(walk(k))) for k in range(5)])
    # A weak echo the features cannot see, but segmentation found.
    tracker.step(25.0, image(rng, walk(5), amplitude=0.2), GRID, regions(walk(5)), None)
    tr = tracker.tracks[0]
    assert tr.track_id == 1 and tr.seen and tracker.report.reseeded == 1
    assert math.hypot(tr.mean[0] - walk(5)[0], tr.mean[1] - walk(5)[1]) < 0.4


def test_time_going_back_is_refused_and_a_reset_restarts_with_new_ids():
    rng = np.random.default_rng(13)
    tracker = GpfTracker(rng=np.random.default_rng(14))
    run(tracker, [(image(rng, walk(k)), regions(walk(k))) for k in range(3)])
    before = tracker.records()
    with pytest.raises(TimeWentBack, match='frame at .* before the previous one'):
        tracker.step(1.0, image(rng, walk(0)), GRID, regions(walk(0)), None)
    assert np.array_equal(tracker.records(), before) and len(before) == 1
    tracker.reset()                 # the caller's decision: a new recording
    rec = tracker.step(1.0, image(rng, walk(0)), GRID, regions(walk(0)), None)
    assert rec['track_id'].tolist() == [2]


def test_bad_input_raises_with_a_reason():
    tracker = GpfTracker(rng=np.random.default_rng(15))
    with pytest.raises(GpfInputError, match='grid says'):
        tracker.step(0.0, np.ones((10, 10)), GRID)
    with pytest.raises(GpfInputError, match='2-D'):
        tracker.step(0.0, np.ones(5), GRID)
    with pytest.raises(GpfInputError, match='fields x and y'):
        tracker.step(0.0, np.ones(GRID.shape), GRID, np.zeros(2, [('range', '<f8')]))
    with pytest.raises(GpfInputError, match='not finite'):
        tracker.step(math.nan, np.ones(GRID.shape), GRID)
    with pytest.raises(ValueError, match='Generator'):
        GpfTracker()
    with pytest.raises(ValueError, match='method'):
        GpfTracker(rng=np.random.default_rng(0), method='kalman')
    # Regions without a finite position are skipped and counted.
    rec = regions((10.0, 0.0), (np.nan, 1.0))
    tracker.step(0.0, image(np.random.default_rng(0), (10.0, 0.0)), GRID, rec)
    assert tracker.report.bad_regions == 1 and len(tracker.tracks) == 1


def test_same_seed_same_tracks():
    rng = np.random.default_rng(16)
    frames = [(image(rng, walk(k)), regions(walk(k))) for k in range(6)]
    a = run(GpfTracker(rng=np.random.default_rng(17)), frames)
    b = run(GpfTracker(rng=np.random.default_rng(17)), frames)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_adaptive_fusion_is_weighted_while_another_track_is_in_the_cloud():
    # The crossing switch: another track's prediction inside this track's cloud makes af WF (tr.a
    # holds the fuzzy weights of eq. 14; None after MF); outside the gate, or with switch cues,
    # eq. 18 decides alone.
    rng = np.random.default_rng(5)
    frames = [(image(rng, walk(k)), regions(walk(k))) for k in range(4)]

    def update(config, others, seed=6):
        t = GpfTracker(config, np.random.default_rng(2))
        run(t, frames[:3])
        tr = t.tracks[0]
        t.predict_track(tr, 5.0)
        t.rng = np.random.default_rng(seed)
        t.update_track(tr, t.prepare(frames[3][0], GRID), others)
        return tr

    low = {'fusion.thresholds': [0.01]}          # every cue reliable: eq. 18 alone says MF
    tr = update(GpfConfig.from_flat(low), None)
    inside = tr.mean[None, :2] + np.array([[0.3, -0.2]])
    far = tr.mean[None, :2] + np.array([[8.0, 0.0]])
    for seed in range(4):
        assert update(GpfConfig.from_flat(low), None, seed).a is None
        assert update(GpfConfig.from_flat(low), far, seed).a is None
        assert update(GpfConfig.from_flat({**low, 'fusion.switch': 'cues'}), inside, seed).a is None
        assert update(GpfConfig.from_flat(low), inside, seed).a is not None
        assert update(GpfConfig.from_flat({**low, 'fusion.gate': 0.01}), inside, seed).a is None
    with pytest.raises(ConfigError):
        GpfConfig.from_flat({'fusion.switch': 'bimodal'})


def test_sir_baseline_and_ekf_baseline_follow_the_target():
    rng = np.random.default_rng(18)
    frames = [(image(rng, walk(k)), regions(walk(k))) for k in range(12)]
    sir = GpfTracker(rng=np.random.default_rng(19), method='sir')
    recs = run(sir, frames)
    for tr in sir.tracks:
        assert tr.particles.shape == (300, 4) and tr.weights.sum() == pytest.approx(1.0)
    assert math.hypot(recs[-1]['x'][0] - walk(11)[0], recs[-1]['y'][0] - walk(11)[1]) < 0.4
    ekf = EkfTracker()
    out = [ekf.step(5.0 * k, reg, (0.0, 0.0, 0.0)) for k, (_, reg) in enumerate(frames)]
    assert out[-1]['confirmed'][0] == 1 and out[-1]['track_id'][0] == 1
    assert math.hypot(out[-1]['x'][0] - walk(11)[0], out[-1]['y'][0] - walk(11)[1]) < 0.3
    assert abs(out[-1]['vx'][0] - 0.25) < 0.1
    # A frame without regions: the EKF coasts (and widens); a region far away starts a new track.
    ekf.step(60.0, regions((3.0, -6.0)), (0.0, 0.0, 0.0))
    assert [t.track_id for t in ekf.tracks] == [1, 2] and not ekf.tracks[0].seen


def test_settings_are_checked_and_applied():
    with pytest.raises(ConfigError, match='same for every window'):
        GpfConfig.from_flat({'cues.features': (3.0, 5.0)})
    with pytest.raises(ConfigError, match='one or 5'):
        GpfConfig.from_flat({'fusion.thresholds': (1.0, 2.0)})
    with pytest.raises(ConfigError, match='twice'):
        GpfConfig.from_flat({'cues.features': (3.0, 3.0)})
    with pytest.raises(ConfigError, match='whole'):
        GpfConfig.from_flat({'cues.features': (3.5,)})
    # A window that could be cut at MAX_WINDOW pixels of the cues' pixel is refused at the start.
    with pytest.raises(ConfigError, match=r'cues.window 2.2 m spans up to 44 pixels of cues.pixel 0.1 m'):
        GpfConfig.from_flat({'cues.window': 2.2})
    assert GpfConfig.from_flat({'cues.window': 2.2, 'cues.pixel': 0.11}).cues.window == 2.2
    cfg = GpfConfig.from_flat({'cues.features': (3.0, 24.0), 'fusion.thresholds': (0.0, 1.7)})
    tracker = GpfTracker(cfg, np.random.default_rng(0))
    np.testing.assert_allclose(tracker.thresholds, [0.98, 1.7])     # 0 = the cue's calibrated T_i
    # Changing the cue set re-measures running tracks' templates at their next update.
    rng = np.random.default_rng(20)
    run(tracker, [(image(rng, walk(k)), regions(walk(k))) for k in range(3)])
    tracker.configure(GpfConfig.from_flat({'cues.features': (3.0, 6.0, 24.0)}))
    tracker.step(15.0, image(rng, walk(3)), GRID, regions(walk(3)), None)
    assert tracker.tracks[0].template.shape == (3,) and tracker.tracks[0].track_id == 1


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


def test_window_features_are_the_same_in_one_large_call_and_in_small_ones():
    # A large call quantises the whole image once and computes in chunks; the f06 fallback of a
    # window whose ring has no data is its group's median: equal to calls of one group each.
    rng = np.random.default_rng(11)
    img = rng.exponential(1.0, (40, 30)) * np.where(rng.random((40, 30)) < 0.05, 40.0, 1.0)
    img[:, 20:] = 0.0
    rows, cols = rng.integers(-12, 52, 3000), rng.integers(-12, 42, 3000)
    big = WindowImage(img, max_size=7).features(rows, cols, 7, groups=np.arange(3000) // 10)
    small = np.concatenate([WindowImage(img, max_size=7).features(rows[i:i + 10], cols[i:i + 10], 7)
                            for i in range(0, 3000, 10)])
    # f25-f29 go through BLAS matrix products (core.fls.features.glcm_features), whose round-off
    # depends on how many windows are multiplied at once; every other feature is bit-identical.
    blas = [24, 25, 26, 27, 28]
    np.testing.assert_array_equal(np.delete(big, blas, axis=1), np.delete(small, blas, axis=1))
    np.testing.assert_allclose(big[:, blas], small[:, blas], rtol=1e-12, atol=1e-12)


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

    def outward(k):
        return (4.0 + 0.5 * k, 0.2)

    def history(config, frames):
        tracker = GpfTracker(GpfConfig.from_flat({'lost.max_time': 60.0, **config}), np.random.default_rng(6))
        out = []                                # (tracks, tracks outside) after each frame
        for k, (img, reg) in enumerate(frames):
            tracker.step(5.0 * k, img, grid, reg, (0.0, 0.0, 0.0))
            out.append((len(tracker.tracks), tracker.report.outside))
        return out

    rng = np.random.default_rng(5)
    frames = [(scene(grid, rng, [outward(k)], 8.0), regions(outward(k)) if outward(k)[0] < 8.0 else regions())
              for k in range(16)]
    alive = history({}, frames)
    assert alive[6] == (1, 0)                   # x 7 m: still inside
    first = next(k for k, (_, out) in enumerate(alive) if out)
    # outside_time 2 s < one 5 s frame: ends at the second frame outside, long before max_time.
    assert alive[first] == (1, 1) and alive[first + 1][0] == 0 and first <= 12
    assert history({'lost.outside_time': 12.0}, frames)[first + 2][0] == 1
    assert history({'lost.outside_time': 12.0}, frames)[first + 3][0] == 0
    # A frame without any data (a dropout) neither starts nor stops the clock.
    frames[first] = (np.zeros(grid.shape, np.float32), regions())
    alive = history({}, frames)
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


@pytest.mark.parametrize('method', ['gpf', 'sir'])
def test_a_track_born_from_one_region_is_not_confirmed_by_its_own_template(method):
    """A static echo (a persistent speckle peak) segmented as a region in one frame only: the track
    born on it finds its template again in every later image, but only a region at the track is an
    independent detection, so it stays tentative; a second region at it confirms it."""
    rng = np.random.default_rng(21)
    echo = (10.0, 0.5)
    frames = [(image(rng, echo), regions(echo))] + [(image(rng, echo), regions()) for _ in range(9)]
    tracker = GpfTracker(rng=np.random.default_rng(22), method=method)
    recs = run(tracker, frames)
    assert all(len(r) == 1 for r in recs), [len(r) for r in recs]
    assert tracker.tracks[0].seen and tracker.tracks[0].hits == 1
    assert not any(r['confirmed'].any() for r in recs)
    tracker.step(50.0, image(rng, echo), GRID, regions(echo), (0.0, 0.0, 0.0))
    assert tracker.tracks[0].confirmed and tracker.tracks[0].hits == 2

"""FlsProcessor: frames per sweep or sector, records, bad input, a moving platform, time jumps."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.fls import FlsConfig, FlsInputError, FlsProcessor, region_features
from sonar_tracking.core.records import FEATURE_NAMES, REGION_DTYPE
from sonar_tracking.core.timeline import TimeWentBack
from sonar_tracking.sim import SimConfig, Simulator
from sonar_tracking.studies.fls_segmentation import score_frames, simulate_frames


def sectors(scenario='fls14', seed=0, n=None, **overrides):
    sim = Simulator(SimConfig.for_scenario(scenario, **overrides), np.random.default_rng(seed))
    out = []
    while n is None or len(out) < n:
        s = sim.next_sector()
        if s is None:
            break
        out.append(s)
    return out


def run(processor, secs):
    frames = []
    for s in secs:
        frames += processor.add_sector(s.amplitudes, s.geometry, s.pose, s.stamp)
    return frames


def test_one_frame_per_sweep_stamped_with_the_sweep_end():
    secs = sectors(duration=26.0)
    frames = run(FlsProcessor(), secs)
    ends = [s.stamp for s in secs if s.end_of_sweep]
    assert [f.stamp for f in frames] == pytest.approx(ends[:len(frames)])
    assert len(frames) >= len(ends) - 1  # the last sweep may only be seen when the next starts
    assert sum(f.sectors for f in frames) <= len(secs)
    f = frames[-1]
    assert f.image.dtype == np.float32 and f.image.shape == f.grid.shape and f.labels.shape == f.grid.shape
    assert (f.image >= 0).all() and (f.image == 0).any()  # 0 outside the fan
    assert set(f.timings) == {'filter_paint', 'image', 'segment', 'features'}


def test_sector_mode_emits_a_frame_per_sector():
    secs = sectors(n=25)
    frames = run(FlsProcessor(FlsConfig.from_flat({'image.publish': 'sector'})), secs)
    # One per sector, plus the late-found ends of the first two sweeps (emitted before painting).
    assert len(secs) <= len(frames) <= len(secs) + 2


def test_records_describe_the_regions_of_the_image():
    frames = run(FlsProcessor(), sectors('fls12', seed=4, duration=40.0))
    f = next(fr for fr in reversed(frames) if len(fr.regions) >= 2)
    r = f.regions
    assert r.dtype == REGION_DTYPE and r['region_id'].tolist() == list(range(1, len(r) + 1))
    feats = region_features(f.image, f.labels, len(r))
    assert np.stack([r[name] for name in FEATURE_NAMES], axis=1) == pytest.approx(feats, rel=1e-12)
    px, py, yaw = f.sensor_pose
    assert r['range'] == pytest.approx(np.hypot(r['x'] - px, r['y'] - py))
    assert r['bearing'] == pytest.approx(np.arctan2(r['y'] - py, r['x'] - px) - yaw)
    for k, rec in enumerate(r, start=1):
        rows, cols = np.nonzero(f.labels == k)
        assert rec['f01'] == rows.size
        # The centroid lies within the region's pixel box.
        x, y = f.grid.pixel_to_point(np.array([rows.min(), rows.max()]), np.array([cols.min(), cols.max()]))
        assert x.min() - 0.1 <= rec['x'] <= x.max() + 0.1 and y.min() - 0.1 <= rec['y'] <= y.max() + 0.1


@pytest.mark.parametrize('change, match', [
    (lambda a, g: (a[:, :-1], g), 'geometry says'),
    (lambda a, g: (a[:0], g), 'empty'),
    (lambda a, g: (np.where(np.arange(a.shape[1]) == 2, np.nan, a).astype(np.float32), g), 'NaN or infinite'),
    (lambda a, g: (-a, g), 'negative'),
    (lambda a, g: (a[None], g), '2-D'),
    (lambda a, g: (a.astype(np.complex64), g), 'dtype'),
])
def test_bad_sector_is_refused_and_nothing_changes(change, match):
    secs = sectors(n=24)
    good = FlsProcessor()
    want = run(good, secs)
    p = FlsProcessor()
    got = run(p, secs[:12])
    bad_a, bad_g = change(secs[12].amplitudes, secs[12].geometry)
    with pytest.raises(FlsInputError, match=match):
        p.add_sector(bad_a, bad_g, secs[12].pose, secs[12].stamp)
    got += run(p, secs[12:])
    assert [f.stamp for f in got] == [f.stamp for f in want]
    assert np.array_equal(got[-1].image, want[-1].image)
    with pytest.raises(FlsInputError, match='pose'):
        p.add_sector(secs[0].amplitudes, secs[0].geometry, (math.nan, 0.0, 0.0), 1e6)


def test_time_going_back_is_refused_unchanged_and_reset_starts_a_new_image():
    secs = sectors(n=30)
    p = FlsProcessor()
    run(p, secs)
    before = (p.resets, p._pending, p._last_stamp)
    s = secs[0]                 # a looping recording: the caller decides (the node restarts)
    with pytest.raises(TimeWentBack, match='sector at .* before the previous one'):
        p.add_sector(s.amplitudes, s.geometry, s.pose, s.stamp)
    assert (p.resets, p._pending, p._last_stamp) == before
    p.reset()
    frames = run(p, secs[:12])
    assert p.resets == 1 and frames[0].sectors == 11


def test_too_many_pixels_is_an_input_error():
    p = FlsProcessor(FlsConfig.from_flat({'image.resolution': 0.005, 'image.max_side': 2000}))
    s = sectors(n=1)[0]
    with pytest.raises(FlsInputError, match='image.max_side'):
        p.add_sector(s.amplitudes, s.geometry, s.pose, s.stamp)


def test_moving_platform_world_frame_puts_regions_on_the_targets():
    """Sea trial (§5.2): the AUV moves at 0.5 m/s; sectors painted at their world poses give
    regions on the targets' echoes, in the world frame, as the image follows the platform. (At
    30 dB, to test the geometry: at the scenario's 20 dB the sphere, one 8 cm range bin deep at
    30-40 m, is often below the threshold.)"""
    frames = list(simulate_frames('sea_trial', 11, first=1, every=1, max_frames=12, snr_db=30.0))
    s = score_frames(frames, min_snr_db=15.0)
    assert s.targets >= 16 and s.detection_rate >= 0.95 and s.false_per_frame <= 0.5
    xs = [f.frame.grid.origin_x for f in frames]
    assert xs[-1] > xs[0] + 20.0  # the image moved with the AUV (about 5 m per 10 s sweep)


def test_all_zero_sector_is_valid_and_has_no_regions():
    """Nothing seen (open water below the gain floor, or blanked) is valid input (the sector rule)."""
    secs = sectors(n=24)
    p = FlsProcessor()
    frames = []
    for s in secs:
        frames += p.add_sector(np.zeros_like(s.amplitudes), s.geometry, s.pose, s.stamp)
    assert frames and all(len(f.regions) == 0 and not f.image.any() for f in frames)

"""The FLS front end on real-sonar input: exact zeros, 8-bit dB counts, static structure.

Frames are small synthetic imaging-sonar sectors made here with a seeded Generator (all beams at
once, 10 Hz): exponential speckle, a wall across the fan, a seabed band, transducer ringdown, and
targets moving at 0.5-1 m/s.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sonar_tracking.core.background import range_profile as background_level
from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.fls import FlsConfig, FlsInputError, FlsProcessor
from sonar_tracking.core.intensity import decode
from sonar_tracking.core.sector import SectorGeometry

FAN = SectorGeometry(angle_min=math.radians(-14.4), angle_increment=math.radians(0.3), n_beams=97,
                     range_min=1.0, range_max=20.0, n_bins=381, scan_time=0.1)
WALL_X, BAND, RING = 15.0, (9.0, 9.6), 1.6
# The rules below act from the first frame; the warm-up (tested on its own) would hold the first ones back.
STRUCTURE = {'structure.enabled': True, 'structure.max_length': 6.0, 'structure.elongated_length': 2.5,
             'structure.warmup': False}


def intensity(rng, t, targets=(), structure=True, geometry=FAN, pose=(0.0, 0.0)):
    """One frame of linear intensity: speckle of mean 1, a wall at x = 15 m (|y| < 3.5 m) with a
    weaker fringe, a seabed band, ringdown near the transducer, targets ``(x0, y0, vx, vy)`` 0.6 m
    across (world frame; the sonar at ``pose`` looks along x)."""
    r, b = geometry.ranges()[:, None], geometry.bearings()[None, :]
    x, y = pose[0] + r * np.cos(b), pose[1] + r * np.sin(b)
    a = rng.exponential(1.0, geometry.shape)
    if structure:
        wall = np.abs(x - WALL_X) + np.maximum(np.abs(y) - 3.5, 0.0)
        a = np.where(wall < 0.15, 40.0, np.where(wall < 0.4, 6.0, 1.0)) * a
        a = np.where((r >= BAND[0]) & (r < BAND[1]), 5.0, 1.0) * a
        a = np.where(r < RING, 30.0, 1.0) * a
    for x0, y0, vx, vy in targets:
        a = np.where(np.hypot(x - x0 - vx * t, y - y0 - vy * t) < 0.3, 30.0, 1.0) * a
    return a.astype(np.float32)


def on_structure(x, y, margin=0.5):
    r = np.hypot(x, y)
    wall = np.abs(x - WALL_X) + np.maximum(np.abs(y) - 3.5, 0.0)
    return (wall < 0.4 + margin) | ((r > BAND[0] - margin) & (r < BAND[1] + margin)) | (r < RING + margin)


def test_background_level_ignores_exact_zeros():
    rng = np.random.default_rng(2)
    profile = np.linspace(1.0, 10.0, 400) ** 2
    raw = (rng.exponential(1.0, (400, 100)) * profile[:, None]).astype(np.float32)
    raw[rng.random(raw.shape) < np.linspace(0.45, 0.73, 400)[:, None]] = 0.0   # 45-73 % no data
    raw[300:310] = 0.0                                                          # bins without any data
    raw[310:320, 5:] = 0.0                                                      # bins with 5 cells of data
    level = background_level(raw, 41)
    ratio = level / profile
    assert np.abs(ratio[30:-30] - 1.0).max() < 0.15 and abs(np.median(ratio) - 1.0) < 0.05
    # Bins with too little data take their neighbours' level.
    assert level[300:320] == pytest.approx(profile[300:320], rel=0.15)
    assert background_level(np.zeros((50, 20), np.float32), 5) == pytest.approx(1.0)


def didson(rng, geometry):
    """A DIDSON-like frame of empty water: 8-bit dB counts, 45 % of each near bin and 73 % of each far
    bin exactly 0 (below the gain floor)."""
    a = intensity(rng, 0.0, structure=False, geometry=geometry)
    floor = np.interp(geometry.ranges(), [geometry.range_min, geometry.range_max], [0.6, 1.32])[:, None]
    counts = 1 + np.round(20 * np.log10(np.maximum(a, 1e-12) / floor) * 255 / 60.0)
    return np.where(a <= floor, 0, np.clip(counts, 1, 255)).astype(np.uint8)


@pytest.mark.parametrize('coding', ['linear_amplitude', 'db'])
def test_empty_water_with_a_majority_of_zeros_gives_no_regions(coding):
    """Regression: the per-bin median was 0 where most cells are 0, the far bins were normalised by
    the floor and the far half of the fan became one region (20 m^2 a frame in this scene)."""
    fan = dataclasses.replace(FAN, range_max=10.0)
    rng = np.random.default_rng(1)
    p = FlsProcessor(FlsConfig.from_flat({'intensity.coding': coding}))
    regions, zeros = [], []
    for k in range(40):
        a = didson(rng, fan)
        zeros.append((a == 0).mean())
        regions += [len(f.regions) for f in p.add_sector(a, fan, (0.0, 0.0, 0.0), 0.1 * k)]
    assert 0.55 < np.mean(zeros) < 0.65 and len(regions) == 40
    assert np.mean(regions) < 0.1


def test_db_coded_counts_give_the_frames_of_their_linear_amplitude():
    rng = np.random.default_rng(4)
    counts = rng.integers(0, 256, FAN.shape).astype(np.uint8)
    coded = FlsProcessor(FlsConfig.from_flat({'intensity.coding': 'db', 'intensity.db_span': 50.0}))
    plain = FlsProcessor()
    got = coded.add_sector(counts, FAN, (0.0, 0.0, 0.0), 0.0)[0]
    want = plain.add_sector(decode(counts, 'db', db_span=50.0, full_scale=255.0), FAN, (0.0, 0.0, 0.0), 0.0)[0]
    assert np.array_equal(got.image, want.image) and np.array_equal(got.regions, want.regions)
    # dB carried as floats may be negative; in a linear coding that is an error.
    db = (20 * np.log10(rng.exponential(1.0, FAN.shape))).astype(np.float32)
    assert (db < 0).any()
    FlsProcessor(FlsConfig.from_flat({'intensity.coding': 'db'})).add_sector(db, FAN, (0.0, 0.0, 0.0), 0.0)
    with pytest.raises(FlsInputError, match='negative'):
        plain.add_sector(db, FAN, (0.0, 0.0, 0.0), 1.0)


def test_ringdown_is_blanked_and_max_range_cuts_the_image():
    rng = np.random.default_rng(5)
    p = FlsProcessor(FlsConfig.from_flat({'intensity.blank_range': 2.0, 'intensity.max_range': 12.0}))
    f = p.add_sector(intensity(rng, 0.0), FAN, (0.0, 0.0, 0.0), 0.0)[0]
    x, y = f.grid.pixel_centres()
    r, inside = np.hypot(x, y), np.abs(np.arctan2(y, x)) < math.radians(14.0)
    assert f.image[r < 1.9].max() == 0.0 and (f.image[(r > 2.2) & (r < 11.5) & inside] > 0).mean() > 0.95
    assert r[f.image > 0].max() < 12.2 and not (f.regions['range'] < 2.0).any()


def run(flat, frames, targets=(), seed=0):
    rng = np.random.default_rng(seed)
    p = FlsProcessor(FlsConfig.from_flat(flat))
    per_frame, structure, seen = [], [], []
    for k in range(frames):
        t = 0.1 * k
        for f in p.add_sector(intensity(rng, t, targets), FAN, (0.0, 0.0, 0.0), t):
            reg = f.regions
            per_frame.append(len(reg))
            structure.append(int(on_structure(reg['x'], reg['y']).sum()))
            for x0, y0, vx, vy in targets:
                tx, ty = x0 + vx * t, y0 + vy * t
                if abs(math.atan2(ty, tx)) < math.radians(13.0):
                    seen.append(bool((np.hypot(reg['x'] - tx, reg['y'] - ty) < 0.6).any()))
    return np.array(per_frame), np.array(structure), np.array(seen)


@pytest.mark.parametrize('speed', [0.5, 1.0])
def test_static_structure_regions_are_rejected_and_moving_targets_kept(speed):
    # One target crosses the fan before the background has learnt anything, one after (at 6 m and 12 m).
    targets = ((6.0, -1.5, 0.0, speed), (12.0, 2.8 + 25.0 * speed, 0.0, -speed))
    _, structure0, seen0 = run({}, 320, targets)
    n, structure, seen = run(STRUCTURE, 320, targets)
    assert structure0.mean() >= 2.0                   # wall, band (and ringdown) without rejection
    assert structure.sum() == 0 and n.mean() < 0.5    # shape gates from the first frame, persistence later
    assert seen.size > 40 and seen.mean() >= 0.95 and seen0.mean() >= 0.95


def test_persistence_alone_rejects_structure_after_min_echo_time():
    n, structure, seen = run({'structure.enabled': True, 'structure.warmup': False}, 330,
                             ((12.0, 2.8 + 25.0 * 0.75, 0.0, -0.75),))
    assert structure[:70].mean() >= 2.0               # nothing vetoed before it echoed 7.5 s
    assert structure[80:].sum() == 0                  # then every structure region
    assert seen.size > 40 and seen.mean() >= 0.95


def test_moving_sonar_learns_static_piles_in_the_world_frame():
    """Piles (small, static in the world) pass every shape gate; the sonar drives towards them at
    0.5 m/s, so they move through its cells, and only the world-frame image background removes
    them. A target crossing at 0.75 m/s stays."""
    piles = tuple((x, y, 0.0, 0.0) for x, y in ((12.0, -1.0), (13.5, 0.5), (15.0, -0.3)))
    target = (20.0, 3.5 + 17.0 * 0.75, 0.0, -0.75)  # in view from 17 s to 26 s
    rng = np.random.default_rng(6)
    p = FlsProcessor(FlsConfig.from_flat(STRUCTURE))
    on_piles, seen = [], []
    for k in range(300):
        t = 0.1 * k
        pose = (-5.0 + 0.5 * t, 0.0, 0.0)
        frames = p.add_sector(intensity(rng, t, piles + (target,), structure=False, pose=pose), FAN, pose, t)
        for f in frames:
            reg = f.regions
            on_piles.append(sum(int((np.hypot(reg['x'] - x, reg['y'] - y) < 0.6).sum()) for x, y, _, _ in piles))
            tx, ty = target[0], target[1] + target[3] * t
            if abs(math.atan2(ty, tx - pose[0])) < math.radians(13.0):
                seen.append(bool((np.hypot(reg['x'] - tx, reg['y'] - ty) < 0.6).any()))
    on_piles = np.array(on_piles)
    assert on_piles[:70].mean() > 2.5 and on_piles[80:].sum() == 0
    assert len(seen) > 40 and np.mean(seen) >= 0.95


def test_max_range_beyond_what_the_image_allows_is_refused_at_construction():
    with pytest.raises(ConfigError, match='image.max_side'):
        FlsConfig.from_flat({'intensity.max_range': 300.0, 'image.resolution': 0.05})
    FlsConfig.from_flat({'intensity.max_range': 100.0, 'image.resolution': 0.05})


def test_the_warm_up_holds_every_region_back_until_the_background_can_judge():
    """With ``structure.warmup`` nothing comes out for ``min_echo_time`` after the start (structure in
    view from the first ping cannot be told from a target before), then the rules act as usual."""
    rng = np.random.default_rng(8)
    p = FlsProcessor(FlsConfig.from_flat(STRUCTURE | {'structure.warmup': True, 'structure.min_echo_time': 3.0}))
    target = (12.0, 2.5, 0.0, -0.4)                 # in view all along
    counts = []
    for k in range(120):
        t = 0.1 * k
        for f in p.add_sector(intensity(rng, t, (target,)), FAN, (0.0, 0.0, 0.0), t):
            counts.append((f.stamp, len(f.regions)))
    early = [n for s, n in counts if s < 3.0]
    late = [n for s, n in counts if s >= 3.0]
    assert early and sum(early) == 0 and len(late) > 50 and np.mean([n >= 1 for n in late]) >= 0.9

"""The detector on real-sonar input: intensity decoding, the max_detections cut, static-structure rejection.

The structured scenes are small synthetic polar sectors made here with a seeded Generator: Rayleigh
clutter, a bright wall (static in the world), a seabed band (a range band, static in the sensor
frame) and targets moving at 0.5-1 m/s past them.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.detection import ActiveDetector, DetectionInputError, DetectorConfig
from sonar_tracking.core.intensity import decode
from sonar_tracking.core.sector import SectorGeometry

GEOM = SectorGeometry(angle_min=math.radians(-45.0), angle_increment=math.radians(0.5), n_beams=181,
                      range_min=2.0, range_max=50.0, n_bins=241, scan_time=1.0)
BAND = (30.0, 31.0)          # seabed band: ranges from the sonar
# The rules below act from the first scan; the warm-up (tested on its own) would hold the first ones back.
STRUCTURE = {'esc.enabled': False, 'cells.grouping': 'connected', 'structure.enabled': True,
             'structure.max_length': 6.0, 'structure.elongated_length': 3.0, 'structure.warmup': False}


def scene(rng, t, pose=(0.0, 0.0, 0.0), targets=()):
    """Amplitudes of one scan: clutter, a wall at x = 40 m (|y| < 12 m, world frame) with flickering
    edges, the seabed band and targets ``(x0, y0, vx, vy)`` (1 m across)."""
    r = GEOM.ranges()[:, None]
    b = GEOM.bearings()[None, :] + pose[2]
    x, y = pose[0] + r * np.cos(b), pose[1] + r * np.sin(b)
    a = rng.rayleigh(0.8, GEOM.shape)                      # P(a > 3) = 9e-4
    wall = np.abs(x - 40.0) + np.maximum(np.abs(y) - 12.0, 0.0)
    a = np.where(wall < 0.3, 15.0 * rng.rayleigh(1.0, GEOM.shape), a)
    a = np.where((wall >= 0.3) & (wall < 0.6), 3.0 * rng.rayleigh(1.0, GEOM.shape), a)
    band = (r >= BAND[0]) & (r < BAND[1]) & (x == x)
    a = np.where(band, rng.rayleigh(3.0, GEOM.shape), a)   # echoes in 61 % of scans
    for x0, y0, vx, vy in targets:
        a = np.where(np.hypot(x - x0 - vx * t, y - y0 - vy * t) < 0.5, 8.0 * rng.rayleigh(1.0, GEOM.shape), a)
    return a.astype(np.float32)


def run(flat, scans, targets=(), speed=0.0, seed=0):
    """Per scan: detections on the wall, on the band, and whether each target in view was detected.
    A static sonar sits at the origin, a moving one drives along x from (-10, 0) at ``speed``."""
    rng = np.random.default_rng(seed)
    det = ActiveDetector(DetectorConfig.from_flat(flat))
    wall, band, seen = [], [], []
    for k in range(scans):
        t = float(k)
        pose = (-10.0 + speed * t, 0.0, 0.0) if speed else (0.0, 0.0, 0.0)
        d = det.process(scene(rng, t, pose, targets), GEOM, pose, stamp=t).detections
        wall.append(int(((np.abs(d['x'] - 40.0) < 0.7) & (np.abs(d['y']) < 12.7)).sum()))
        band.append(int(((d['range'] > BAND[0] - 0.2) & (d['range'] < BAND[1] + 0.2)).sum()))
        for x0, y0, vx, vy in targets:
            tx, ty = x0 + vx * t, y0 + vy * t
            if abs(math.atan2(ty, tx - pose[0])) < math.radians(44) and math.hypot(tx - pose[0], ty) < 49:
                seen.append(bool((np.hypot(d['x'] - tx, d['y'] - ty) < 1.0).any()))
    return np.array(wall), np.array(band), np.array(seen)


@pytest.mark.parametrize('speed', [0.5, 1.0])
def test_static_wall_and_band_are_vetoed_and_moving_targets_kept(speed):
    # Targets cross the sector at 12 m and 18 m, from side to side, between the sonar and the band.
    targets = ((12.0, -20.0, 0.0, speed), (18.0, 25.0, 0.0, -speed))
    scans = int(50 / speed) + 20
    wall0, band0, seen0 = run({'esc.enabled': False, 'cells.grouping': 'connected'}, scans, targets)
    wall, band, seen = run(STRUCTURE, scans, targets)
    assert wall0.mean() > 0.5 and band0.mean() > 8.0           # without rejection: detections on both
    # Once structure has echoed min_echo_time (7.5 s; the band, echoing in 61 % of scans, ~12 s) the
    # persistent-echo background removes even the detached fragments of the wall's flickering edge
    # and of the band, which the shape gates cannot judge.
    assert wall[16:].sum() == 0 and band[16:].sum() == 0
    assert seen.size > 40 and seen.mean() >= 0.95 and seen.mean() >= seen0.mean() - 0.02


def test_shape_gates_reject_wall_and_band_from_the_first_scan():
    rng = np.random.default_rng(1)
    target = ((15.0, 2.0, 0.0, 0.0),)
    a = scene(rng, 0.0, targets=target)
    r, b = GEOM.ranges()[:, None], GEOM.bearings()[None, :]
    x, y = r * np.cos(b), r * np.sin(b)
    a[(r >= BAND[0]) & (r < BAND[1]) & (x == x)] = 6.0   # a solid band, and a solid wall face
    a[np.abs(x - 40.0) + np.maximum(np.abs(y) - 12.0, 0.0) < 0.6] = 20.0
    gates = STRUCTURE | {'structure.persistence': 1.0}
    got = ActiveDetector(DetectorConfig.from_flat(gates)).process(a, GEOM)
    plain = ActiveDetector(DetectorConfig.from_flat({'esc.enabled': False, 'cells.grouping': 'connected'})).process(
        a, GEOM)
    d = got.detections
    assert got.structure >= 2 and len(d) == len(plain.detections) - got.structure
    assert not ((d['range'] > BAND[0] - 0.5) & (d['range'] < BAND[1] + 0.5)).any()
    assert not ((np.abs(d['x'] - 40.0) < 0.7) & (np.abs(d['y']) < 12.7)).any()
    assert (np.hypot(d['x'] - 15.0, d['y'] - 2.0) < 0.5).sum() == 1


def test_persistence_alone_vetoes_structure_in_the_papers_cell_mode():
    """No shape gates, every cell its own detection (the ESC paper's cells): once the structure has
    echoed long enough the persistent-echo background alone removes wall and band, and the moving
    target stays."""
    flat = {'esc.enabled': False, 'structure.enabled': True}
    target = ((12.0, -20.0, 0.0, 0.75),)
    wall0, band0, _ = run({'esc.enabled': False}, 40, target)
    wall, band, seen = run(flat, 70, target)
    assert wall0[16:].mean() > 50 and band0[16:].mean() > 100
    assert wall[16:].sum() == 0 and band[16:].sum() == 0
    assert seen.mean() >= 0.95


def test_moving_sonar_uses_both_maps():
    """The sonar drives at 0.5 m/s: the wall is static in the world (world map), the seabed band in
    the sensor frame (sensor map); 'auto' rejects both, each map alone only its own."""
    flat = {'esc.enabled': False, 'cells.grouping': 'connected', 'structure.enabled': True, 'structure.warmup': False}
    target = ((20.0, -20.0, 0.0, 0.75),)
    results = {m: run(flat | {'structure.map': m}, 60, target, speed=0.5) for m in ('auto', 'sensor', 'world')}
    wall0, band0, _ = run({'esc.enabled': False, 'cells.grouping': 'connected'}, 60, target, speed=0.5)
    assert wall0[20:].mean() > 0.5 and band0[20:].mean() > 5
    wall, band, seen = results['auto']
    # Wall cells coming into view as the sonar approaches need their own echo time: a stray fragment
    # of the wall's end may pass (one in these 40 scans, against 0.9 a scan without rejection).
    assert wall[20:].sum() <= 2 and band[20:].sum() == 0 and seen.mean() >= 0.9
    assert results['sensor'][0][20:].mean() > 0.3 and results['sensor'][1][20:].sum() == 0
    assert results['world'][0][20:].sum() <= 2 and results['world'][1][20:].mean() > 5


def test_max_detections_keeps_the_strongest_and_counts_the_cut():
    rng = np.random.default_rng(7)
    a = rng.rayleigh(1.0, GEOM.shape).astype(np.float32)
    det = ActiveDetector(DetectorConfig.from_flat({'esc.enabled': False, 'threshold.initial': 2.0,
                                                   'cells.max_detections': 100}))
    r = det.process(a, GEOM)
    above = np.sort(a[a > 2.0])[::-1]
    assert r.found == above.size > 100 and r.cut == above.size - 100 and r.structure == 0
    assert np.sort(r.detections['amplitude'])[::-1] == pytest.approx(above[:100])
    # Every kept detection carries the count density of all detections found.
    window = 0.5 * (GEOM.angle_max - GEOM.angle_min + GEOM.angle_increment) * (50.1 ** 2 - 1.9 ** 2)
    assert r.detections['clutter_density'] == pytest.approx(above.size / window, rel=1e-3)
    uncut = ActiveDetector(DetectorConfig.from_flat({'esc.enabled': False, 'threshold.initial': 2.0,
                                                     'cells.max_detections': 10000})).process(a, GEOM)
    assert uncut.cut == 0 and len(uncut.detections) == above.size


def test_db_coded_mono8_sector_detects_like_its_linear_amplitude():
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 256, GEOM.shape).astype(np.uint8)
    counts[rng.random(GEOM.shape) < 0.5] = 0   # exact zeros: no data
    flat = {'esc.enabled': False, 'threshold.initial': 500.0, 'threshold.maximum': 1000.0}
    coded = ActiveDetector(DetectorConfig.from_flat(flat | {'intensity.coding': 'db', 'intensity.db_span': 80.0}))
    linear = ActiveDetector(DetectorConfig.from_flat(flat))
    got = coded.process(counts, GEOM).detections
    want = linear.process(decode(counts, 'db', db_span=80.0, full_scale=255.0), GEOM).detections
    assert 0 < len(got) == len(want) and np.array_equal(got, want)


def test_blanking_and_max_range_act_on_the_detections():
    a = np.full(GEOM.shape, 10.0, np.float32)
    flat = {'esc.enabled': False, 'intensity.blank_range': 10.0, 'intensity.max_range': 20.0,
            'cells.max_detections': 100000}
    d = ActiveDetector(DetectorConfig.from_flat(flat)).process(a, GEOM).detections
    assert d['range'].min() >= 10.0 and d['range'].max() <= 20.0 and len(d) == 51 * 181


@pytest.mark.parametrize('bad, match', [
    (np.zeros((3, 4), np.float32), 'geometry says'),
    (-np.ones(GEOM.shape, np.float32), 'negative'),
    (np.full(GEOM.shape, np.nan, np.float32), 'NaN'),
    (np.zeros(GEOM.shape, np.complex64), 'dtype'),
])
def test_bad_sectors_are_refused_and_nothing_changes(bad, match):
    det = ActiveDetector(DetectorConfig.from_flat({'structure.enabled': True, 'structure.warmup': False}))
    with pytest.raises(DetectionInputError, match=match):
        det.process(bad, GEOM)
    assert det.scans == 0 and det.background.polar.columns == 0
    with pytest.raises(DetectionInputError, match='stamp'):
        det.process(np.zeros(GEOM.shape, np.float32), GEOM, stamp=math.inf)
    with pytest.raises(DetectionInputError, match='pose'):
        det.process(np.zeros(GEOM.shape, np.float32), GEOM, (math.nan, 0.0, 0.0))
    assert det.scans == 0


def test_a_sector_blanked_entirely_gives_no_detections_and_esc_goes_on():
    det = ActiveDetector(DetectorConfig.from_flat({'intensity.blank_range': 100.0}))
    r = det.process(np.full(GEOM.shape, 50.0, np.float32), GEOM)
    assert len(r.detections) == 0 and r.mean_density == 0.0 and r.next_threshold < r.threshold


def test_reconfigure_keeps_the_threshold_for_intensity_and_structure_changes():
    rng = np.random.default_rng(8)
    det = ActiveDetector(DetectorConfig.from_flat({'structure.enabled': True, 'structure.warmup': False}))
    for k in range(5):
        det.process(scene(rng, float(k)), GEOM, stamp=float(k))
    tau, scans = det.threshold, det.scans
    new = DetectorConfig.from_flat({'structure.enabled': True, 'structure.warmup': False, 'structure.max_length': 6.0,
                                    'intensity.blank_range': 3.0, 'cells.max_detections': 50})
    det.reconfigure(new)
    assert det.threshold == tau and det.scans == scans and det.config is new
    assert det.background.polar.columns == 0                    # a new structure background
    r = det.process(scene(rng, 5.0), GEOM, stamp=5.0)
    assert len(r.detections) <= 50 and r.detections['range'].min() >= 3.0
    with pytest.raises(ValueError, match='new ActiveDetector'):
        det.reconfigure(DetectorConfig.from_flat({'threshold.initial': 4.0}))


def test_the_warm_up_outputs_nothing_while_esc_and_the_background_learn():
    """``structure.warmup``: no detection for ``min_echo_time`` after the start, while ESC adapts as
    usual; then detections flow."""
    rng = np.random.default_rng(12)
    det = ActiveDetector(DetectorConfig.from_flat({'structure.enabled': True, 'structure.min_echo_time': 3.0}))
    out = []
    for k in range(8):
        r = det.process(scene(rng, float(k), targets=((20.0, 0.0, 0.0, 1.0),)), GEOM, stamp=float(k))
        out.append((r.held, len(r.detections), r.found))
    assert [h for h, _, _ in out] == [True] * 3 + [False] * 5
    assert all(n == 0 and found > 0 for _, n, found in out[:3]) and all(n > 0 for _, n, _ in out[3:])
    assert det.threshold != 3.0, 'ESC adapted during the warm-up'

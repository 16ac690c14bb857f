"""Detector rules for imaging sonars at frame rate: ESC leaves the confirmed tracks' detections out of
its clutter density (esc.exclude_radius), and an extended target's detection gets at least the
position spread of the target (cells.target_size)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.detection import ActiveDetector, DetectorConfig, tracked_positions
from sonar_tracking.core.records import TRACK_DTYPE
from sonar_tracking.core.sector import SectorGeometry

GEOMETRY = SectorGeometry(range_min=1.0, range_max=30.0, n_bins=300, angle_min=-0.5, angle_increment=1.0 / 127,
                          n_beams=128)


def _detector(**flat) -> ActiveDetector:
    base = {'threshold.method': 'fixed', 'threshold.initial': 3.0, 'esc.enabled': True,
            'esc.desired_clutter_density': 1e-3, 'cells.max_detections': 100_000}
    return ActiveDetector(DetectorConfig.from_flat({**base, **flat}))


def _frame(rng) -> np.ndarray:
    """Rayleigh amplitudes of unit mean power, a few strong echoes at known cells."""
    a = np.sqrt(rng.standard_exponential(GEOMETRY.shape) * 0.3).astype(np.float32)
    for row, col in ((100, 64), (101, 64), (200, 20), (250, 100)):
        a[row, col] = 10.0
    return a


def _window_area() -> float:
    dr = GEOMETRY.range_resolution
    r_lo, r_hi = GEOMETRY.range_min - dr / 2, GEOMETRY.range_max + dr / 2
    return 0.5 * GEOMETRY.n_beams * GEOMETRY.angle_increment * (r_hi ** 2 - r_lo ** 2)


def test_esc_counts_only_the_detections_away_from_confirmed_tracks():
    rng = np.random.default_rng(41)
    frame = _frame(rng)
    plain = _detector().process(frame, GEOMETRY, stamp=0.0)
    n = len(plain.detections)
    assert n >= 3
    det = _detector(**{'esc.exclude_radius': 1.0})
    assert det.process(frame, GEOMETRY, stamp=0.0).mean_density == pytest.approx(n / _window_area())
    # A confirmed track on the echo at row 100: the detections within 1 m of it leave the count,
    # and its disc (inside the window) leaves the area.
    d = plain.detections
    track = np.array([[d['x'][0], d['y'][0]]])
    det = _detector(**{'esc.exclude_radius': 1.0})
    result = det.process(frame, GEOMETRY, stamp=0.0, tracked_xy=track)
    near = np.hypot(d['x'] - track[0, 0], d['y'] - track[0, 1]) <= 1.0
    assert 1 <= near.sum() < n
    assert result.mean_density == pytest.approx((n - near.sum()) / (_window_area() - math.pi))
    # Tracks that are not finite are ignored.
    det = _detector(**{'esc.exclude_radius': 1.0})
    nan_track = np.array([[np.nan, 1.0]])
    assert det.process(frame, GEOMETRY, stamp=0.0, tracked_xy=nan_track).mean_density == pytest.approx(
        n / _window_area())


def test_tracked_positions_takes_confirmed_or_likely_finite_tracks():
    tracks = np.zeros(4, TRACK_DTYPE)
    tracks['x'], tracks['y'] = [1.0, 2.0, np.nan, 4.0], [5.0, 6.0, 7.0, 8.0]
    tracks['confirmed'] = [1, 0, 1, 1]
    tracks['existence'] = [0.99, 0.6, 0.99, 0.99]
    assert tracked_positions(tracks).tolist() == [[1.0, 5.0], [4.0, 8.0]]
    # A tentative track of existence at least esc.exclude_existence counts too.
    assert tracked_positions(tracks, 0.5).tolist() == [[1.0, 5.0], [2.0, 6.0], [4.0, 8.0]]
    assert tracked_positions(tracks, 0.7).tolist() == [[1.0, 5.0], [4.0, 8.0]]
    assert tracked_positions(tracks[:0]).shape == (0, 2)


def test_target_size_floors_the_position_spread_of_small_detections():
    frame = np.full(GEOMETRY.shape, 0.1, np.float32)
    frame[150, 64] = 10.0         # one cell, at bearing about 0
    size = 1.5
    plain = _detector(**{'esc.enabled': False}).process(frame, GEOMETRY, stamp=0.0).detections
    sized = _detector(**{'esc.enabled': False, 'cells.target_size': size}).process(frame, GEOMETRY,
                                                                                   stamp=0.0).detections
    assert len(plain) == len(sized) == 1
    floor = size * size / 12.0
    assert plain['cov_xx'][0] < 0.1 * floor and plain['cov_yy'][0] < 0.1 * floor
    b = sized['bearing'][0]
    # Range and cross-range std both size / sqrt(12): the covariance is that circle, whatever the bearing.
    assert sized['cov_xx'][0] == pytest.approx(floor, rel=1e-3, abs=1e-4 * floor)
    assert sized['cov_yy'][0] == pytest.approx(floor, rel=1e-3)
    assert abs(sized['cov_xy'][0]) < 1e-3 * floor + abs(math.sin(2 * b)) * floor

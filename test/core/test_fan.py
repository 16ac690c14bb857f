"""Polar-to-Cartesian painting: positions, frames, full turns, max hold; simulated targets land where truth says."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.fan import PolarCanvas, fan_extent, to_mono8
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.sim import Scene, SeaKingConfig, SeaKingSonar, Target
from sonar_tracking.sim.motion import StaticTrajectory
from sonar_tracking.sim.shapes import shape

GEOM = SectorGeometry(angle_min=-0.5, angle_increment=0.01, n_beams=101, range_min=1.0, range_max=20.0, n_bins=96)


@pytest.mark.parametrize('pose', [(0.0, 0.0, 0.0), (3.0, -2.0, 0.7)])
def test_a_cell_is_painted_where_it_is(pose):
    canvas = PolarCanvas(-30, 30, -30, 30, 0.05)
    values = np.zeros(GEOM.shape, np.float32)
    i, j = 60, 77
    values[i, j] = 1.0
    canvas.paint(values, GEOM, pose)
    r, b = GEOM.ranges()[i], GEOM.bearings()[j] + pose[2]
    row, col = canvas.pixel_of(pose[0] + r * math.cos(b), pose[1] + r * math.sin(b))
    lit = np.argwhere(canvas.image == 1.0)
    centre = lit.mean(axis=0)
    assert abs(centre[0] - row) < 1.0 and abs(centre[1] - col) < 1.0
    # The lit patch is about one cell: range step x arc length.
    assert len(lit) == pytest.approx(GEOM.range_resolution * r * GEOM.angle_increment / 0.05 ** 2, rel=0.35)


def test_full_turn_leaves_no_holes_and_only_paints_inside_range():
    full = SectorGeometry(angle_min=-math.pi, angle_increment=2 * math.pi / 400, n_beams=400, range_min=0.05,
                          range_max=9.95, n_bins=100)
    canvas = PolarCanvas.with_size(fan_extent(full), 300)
    canvas.paint(np.ones(full.shape), full)
    x, y = canvas.point_of(*np.indices(canvas.image.shape))
    rr = np.hypot(x, y)
    assert np.isfinite(canvas.image[(rr > 0.2) & (rr < 9.9)]).all()
    assert np.isnan(canvas.image[rr > 10.2]).all()


def test_hold_max_and_mono8():
    canvas = PolarCanvas(0, 25, -15, 15, 0.1)
    canvas.paint(np.full(GEOM.shape, 2.0), GEOM)
    canvas.paint(np.full(GEOM.shape, 1.0), GEOM, hold_max=True)
    assert np.nanmin(canvas.image) == 2.0
    img = to_mono8(canvas.image)
    assert img.dtype == np.uint8 and img[np.isnan(canvas.image)].max() == 0


def test_simulated_target_appears_where_truth_says():
    cfg = SeaKingConfig(range_max=20.0, n_bins=400, step_deg=0.45, scan_min_deg=-30.0, scan_max_deg=30.0)
    sonar = SeaKingSonar(cfg, sector_size=20)
    truth = (12.0, 3.0)
    scene = Scene([Target(1, StaticTrajectory(*truth), shape('sphere'), 35.0)], lam=1.0, depth=0.0)
    canvas = PolarCanvas.with_size(sonar.coverage(), 600)
    rng = np.random.default_rng(2)
    while True:
        s = sonar.next_sector(scene, rng)
        canvas.paint(s.amplitudes, s.geometry)
        if s.end_of_sweep:
            break
    img = np.nan_to_num(canvas.image)
    row, col = np.unravel_index(np.argmax(img), img.shape)
    x, y = canvas.point_of(row, col)
    # The sphere's specular point faces the sonar, 0.25 m in front of its centre.
    assert math.hypot(x - truth[0], y - truth[1]) < 0.5


def _nearest_cell_image(canvas: PolarCanvas, values: np.ndarray, geometry: SectorGeometry, pose) -> np.ndarray:
    """Independent reference: every pixel of the canvas, nearest cell by bearing and range, no window."""
    x, y = canvas.point_of(*np.indices(canvas.image.shape))
    dx, dy = x - pose[0], y - pose[1]
    rng = np.hypot(dx, dy)
    off = np.remainder(np.arctan2(dy, dx) - pose[2] - geometry.angle_min + 0.5 * geometry.angle_increment,
                       2 * math.pi) - 0.5 * geometry.angle_increment
    j = np.rint(off / geometry.angle_increment)
    dr = geometry.range_resolution if geometry.n_bins > 1 else max(geometry.range_min, 1.0)
    i = np.rint((rng - geometry.range_min) / dr)
    inside = (j >= 0) & (j < geometry.n_beams) & (i >= 0) & (i < geometry.n_bins)
    out = np.full(canvas.image.shape, np.nan, np.float32)
    out[inside] = values[i[inside].astype(int), j[inside].astype(int)]
    return out


GEOMETRIES = [
    GEOM,
    SectorGeometry(math.radians(-45), math.radians(0.9), 10, 0.025, 29.975, 600),
    SectorGeometry(math.radians(170), math.radians(0.9), 30, 0.05, 49.95, 500),
    SectorGeometry(0.1, 0.01, 3, 5.0, 6.0, 5),
]


@pytest.mark.parametrize('geometry', GEOMETRIES)
@pytest.mark.parametrize('pose', [(0.0, 0.0, 0.0), (1.5, -2.0, 0.4), (10.0, 3.0, -2.9)])
def test_cached_paint_is_identical_to_the_per_pixel_mapping(geometry, pose):
    """The cached pixel-to-cell map gives the same image on the first paint and on every repeat."""
    rng = np.random.default_rng(3)
    canvas = PolarCanvas.with_size(fan_extent(geometry, margin=15.0), 300)
    held = PolarCanvas.with_size(fan_extent(geometry, margin=15.0), 300)
    peak = np.full(canvas.image.shape, np.nan, np.float32)
    for _ in range(3):
        values = rng.random(geometry.shape).astype(np.float32)
        canvas.paint(values, geometry, pose)
        held.paint(values, geometry, pose, hold_max=True)
        reference = _nearest_cell_image(canvas, values, geometry, pose)
        peak = np.fmax(peak, reference)
        np.testing.assert_array_equal(canvas.image, reference)
        np.testing.assert_array_equal(held.image, peak)
    assert len(canvas._maps) == 1


def test_cell_map_cache_is_bounded():
    canvas = PolarCanvas(-30, 30, -30, 30, 0.1, cache_pixels=50_000)
    values = np.ones(GEOM.shape, np.float32)
    for k in range(20):
        canvas.paint(values, GEOM, (0.1 * k, 0.0, 0.0))
    assert canvas._cached <= 50_000 or len(canvas._maps) == 1
    assert canvas._cached == sum(p.size for p, _ in canvas._maps.values())
    assert 1 <= len(canvas._maps) < 20

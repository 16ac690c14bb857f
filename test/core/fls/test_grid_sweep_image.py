"""Image building: the pixel <-> metres grid, sweep detection from geometry, the Cartesian builder."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.fls import ImageBuilder, ImageConfig, ImageGrid, SweepTracker, canvas_for, grid_image
from sonar_tracking.core.fls.image import ImageTooLargeError
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.sim import SeaKingConfig, SeaKingSonar


def test_grid_follows_the_occupancy_grid_convention():
    g = ImageGrid(resolution=0.5, width=4, height=3, origin_x=10.0, origin_y=-2.0)
    # Cell (row j, col i) centre = origin + ((i + .5) res, (j + .5) res).
    x, y = g.pixel_to_point(2, 1)
    assert (x, y) == pytest.approx((10.75, -0.75))
    xs, ys = g.pixel_centres()
    assert xs.shape == (3, 4) and xs[0, 0] == pytest.approx(10.25) and ys[2, 0] == pytest.approx(-0.75)
    # A rotated origin is a pose: rows and columns turn with it, and the mapping inverts exactly.
    r = ImageGrid(resolution=0.2, width=50, height=40, origin_x=3.0, origin_y=1.0, origin_yaw=0.7)
    rows, cols = np.random.default_rng(0).uniform(-1, 50, (2, 100))
    back = r.point_to_pixel(*r.pixel_to_point(rows, cols))
    assert np.allclose(back, (rows, cols))
    x0, y0 = r.pixel_to_point(-0.5, -0.5)
    x1, y1 = r.pixel_to_point(-0.5, 9.5)  # ten columns along the grid x axis
    assert (x0, y0) == pytest.approx((3.0, 1.0))
    assert math.atan2(y1 - y0, x1 - x0) == pytest.approx(0.7) and math.hypot(x1 - x0, y1 - y0) == pytest.approx(2.0)
    with pytest.raises(ValueError, match='resolution'):
        ImageGrid(resolution=0.0, width=1, height=1, origin_x=0.0, origin_y=0.0)


def sectors_of(cfg: SeaKingConfig, sector_size: int, n: int):
    sonar = SeaKingSonar(cfg, sector_size)
    plans = [sonar.plan() for _ in range(n)]
    out = []
    for p in plans:
        bearings = p.bearings if p.direction > 0 else p.bearings[::-1]
        period = cfg.ping_period if p.direction > 0 else -cfg.ping_period
        g = SectorGeometry(angle_min=math.remainder(float(bearings[0]), 2 * math.pi),
                           angle_increment=math.radians(cfg.step_deg), n_beams=len(bearings), range_min=0.05,
                           range_max=30.0, n_bins=10, ping_period=period, scan_time=cfg.sweep_time)
        out.append((g, p.end_of_sweep))
    return out


@pytest.mark.parametrize('sector_size', [1, 7, 10, 101])
def test_sweep_ends_found_from_geometry_in_sector_mode(sector_size):
    cfg = SeaKingConfig(step_deg=0.9, scan_min_deg=-45.0, scan_max_deg=45.0)
    tracker = SweepTracker()
    steps = [(tracker.update(g), end) for g, end in sectors_of(cfg, sector_size, 400 // sector_size + 5)]
    ends = [i for i, (_, end) in enumerate(steps) if end]
    found = [i for i, (s, _) in enumerate(steps) if s.ends]
    starts = [i for i, (s, _) in enumerate(steps) if s.starts]
    # The first two sweeps end where the head reverses (seen one sector late, as the next sweep
    # starts); once both limits are known every end is found on time.
    assert starts[0] == 0 and all(e + 1 in starts for e in ends[:2])
    assert [e for e in ends if e > ends[1]] == [f for f in found if f > ends[1]]
    assert set(found) <= set(ends)


def test_sweep_ends_in_continuous_mode_and_all_at_once():
    cfg = SeaKingConfig(step_deg=1.8, scan_min_deg=-180.0, scan_max_deg=180.0, range_max=50.0)
    tracker = SweepTracker()
    steps = [(tracker.update(g), end) for g, end in sectors_of(cfg, 64, 12)]
    assert [s.ends for s, _ in steps] == [end for _, end in steps]
    tracker = SweepTracker()
    multibeam = SectorGeometry(angle_min=-0.5, angle_increment=0.01, n_beams=101, range_min=1, range_max=50,
                               n_bins=100, ping_period=0.0)
    assert tracker.update(multibeam).ends and tracker.update(multibeam).starts


GEOM = SectorGeometry(angle_min=-0.3, angle_increment=0.01, n_beams=61, range_min=1.0, range_max=20.0, n_bins=96,
                      scan_time=2.0)


@pytest.mark.parametrize('pose', [(0.0, 0.0, 0.0), (5.0, -3.0, 0.6)])
def test_a_cell_lands_where_the_grid_says(pose):
    builder = ImageBuilder(ImageConfig(resolution=0.05))
    values = np.zeros(GEOM.shape, np.float32)
    i, j = 50, 40
    values[i, j] = 7.0
    builder.paint(values, GEOM, pose, 0.0)
    img, grid = builder.image()
    rows, cols = np.nonzero(img == 7.0)
    x, y = grid.pixel_to_point(rows.mean(), cols.mean())
    r, b = GEOM.ranges()[i], GEOM.bearings()[j] + pose[2]
    assert np.hypot(x - pose[0] - r * math.cos(b), y - pose[1] - r * math.sin(b)) < 0.1
    assert np.isnan(img).any() and (img[np.isfinite(img)] >= 0).all()
    # Pixels on the global grid: the origin is a multiple of the resolution.
    assert grid.origin_x / 0.05 == pytest.approx(round(grid.origin_x / 0.05))


def test_extent_grows_with_the_sweep_keeps_pixels_and_follows_a_moving_platform():
    builder = ImageBuilder(ImageConfig(resolution=0.1))
    left = GEOM
    right = SectorGeometry(angle_min=0.31, angle_increment=0.01, n_beams=61, range_min=1.0, range_max=20.0, n_bins=96,
                           scan_time=2.0)
    builder.paint(np.ones(left.shape, np.float32), left, (0.0, 0.0, 0.0), 0.0)
    first, g1 = builder.image()
    builder.paint(np.full(right.shape, 2.0, np.float32), right, (0.0, 0.0, 0.0), 0.5)
    both, g2 = builder.image()
    assert g2.height > g1.height  # grew toward +y
    # The first sector's pixels are still there, at the same place.
    rows, cols = np.nonzero(first == 1.0)
    x, y = g1.pixel_to_point(rows, cols)
    r2, c2 = np.rint(g2.point_to_pixel(x, y)).astype(int)
    assert (both[r2, c2] == 1.0).mean() > 0.95
    # A platform that moved on: after two sweep times the old footprints no longer set the extent.
    builder.paint(np.ones(left.shape, np.float32), left, (30.0, 0.0, 0.0), 10.0)
    _, g3 = builder.image()
    assert g3.origin_x > 25.0


def test_too_fine_a_resolution_is_refused_with_the_fix():
    builder = ImageBuilder(ImageConfig(resolution=0.005, max_side=1000))
    with pytest.raises(ImageTooLargeError, match='raise image.resolution or image.max_side'):
        builder.paint(np.ones(GEOM.shape, np.float32), GEOM, (0.0, 0.0, 0.0), 0.0)


def test_canvas_for_a_grid_reproduces_the_grid():
    builder = ImageBuilder(ImageConfig(resolution=0.07))
    builder.paint(np.ones(GEOM.shape, np.float32), GEOM, (1.0, 2.0, 0.3), 0.0)
    img, grid = builder.image()
    canvas = canvas_for(grid)
    canvas.paint(np.ones(GEOM.shape, np.float32), GEOM, (1.0, 2.0, 0.3))
    again, grid2 = grid_image(canvas)
    assert grid2.shape == grid.shape
    assert grid2.origin_x == pytest.approx(grid.origin_x) and grid2.origin_y == pytest.approx(grid.origin_y)
    assert np.array_equal(np.isfinite(again), np.isfinite(img))

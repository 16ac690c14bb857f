"""Static-structure rejection (core/structure.py): shape gates, the echo-frequency rule, both maps."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.core.structure import (
    GridBackground,
    PolarBackground,
    SectorBackground,
    StructureConfig,
    echo_shapes,
    is_structure_shape,
    vetoed_groups,
)

CFG = StructureConfig(enabled=True, time_constant=60.0, persistence=0.5, min_echo_time=7.5, margin=0)


def test_shapes_are_the_sides_of_the_rectangle_with_the_same_moments():
    res = 0.1
    # A 40 x 3 pixel bar rotated by 30 deg, and a single pixel.
    i, j = np.meshgrid(np.arange(40), np.arange(3), indexing='ij')
    u, v = (i.ravel() + 0.5) * res, (j.ravel() + 0.5) * res
    c, s = math.cos(0.5), math.sin(0.5)
    x = np.concatenate([c * u - s * v, [100.0]])
    y = np.concatenate([s * u + c * v, [-50.0]])
    labels = np.concatenate([np.zeros(u.size, int), [1]])
    var = res * res / 12.0
    length, width, area = echo_shapes(x, y, labels, 2, var, 0.0, var, res * res)
    assert length[0] == pytest.approx(4.0, rel=1e-9) and width[0] == pytest.approx(0.3, rel=1e-9)
    assert area[0] == pytest.approx(1.2) and length[1] == pytest.approx(res) and width[1] == pytest.approx(res)


def test_shape_gates_in_metres():
    cfg = StructureConfig(max_length=6.0, max_width=3.0, max_area=10.0, elongated_length=3.0, max_aspect=4.0)
    length = np.array([1.0, 7.0, 2.0, 3.5, 3.5, 2.9, 2.0])
    width = np.array([1.0, 1.0, 2.0, 0.5, 1.0, 0.3, 2.0])
    area = np.array([1.0, 7.0, 4.0, 1.75, 3.5, 0.9, 11.0])
    # target, too long, target, elongated wall, short of aspect, short of length, too large
    assert is_structure_shape(length, width, area, cfg).tolist() == [False, True, False, True, False, False, True]
    wide = StructureConfig(max_width=1.5)
    assert is_structure_shape(np.array([2.0, 2.0]), np.array([1.0, 1.6]), np.array([2.0, 3.2]), wide).tolist() == \
        [False, True]
    assert not is_structure_shape(length, width, area, StructureConfig()).any()  # every gate off


def test_veto_needs_the_fraction_of_cells_on_persistent_cells():
    labels = np.array([0, 0, 0, 0, 1, 1, 2])
    on = np.array([1, 1, 0, 0, 1, 0, 0], bool)
    assert vetoed_groups(labels, 3, on, 0.5).tolist() == [True, True, False]
    assert vetoed_groups(labels, 3, on, 0.75).tolist() == [False, False, False]


@pytest.mark.parametrize('values, match', [
    ({'max_length': 5.0, 'elongated_length': 5.0}, 'elongated_length'),
    ({'max_length': 5.0, 'max_width': 6.0}, 'max_width'),
    ({'persistence': 0.0}, 'persistence'),
    ({'veto_fraction': 0.0}, 'veto_fraction'),
    ({'map': 'odometry'}, 'map'),
    ({'enabled': True, 'persistence': 1.0}, 'rejects nothing'),
])
def test_settings_that_cannot_work_are_refused(values, match):
    with pytest.raises(ConfigError, match=match):
        StructureConfig(**values)


GEOM = SectorGeometry(angle_min=-0.5, angle_increment=0.01, n_beams=101, range_min=1.0, range_max=21.0, n_bins=21,
                      scan_time=1.0)


def looks(background, echo_of_t, times):
    for t in times:
        background.update(echo_of_t(t), GEOM, t)


def test_cell_is_persistent_after_echoing_min_echo_time_in_enough_looks():
    bg = PolarBackground(CFG)
    echo = np.zeros(GEOM.shape, bool)
    echo[5, 50] = True
    looks(bg, lambda t: echo, np.arange(0.0, 7.0))
    assert not bg.persistent(np.array([5]), np.array([50]), GEOM, 7.0)[0]  # echoed 6 s of its 6 s < 7.5 s
    looks(bg, lambda t: echo, np.arange(7.0, 9.0))
    mask = bg.persistent_mask(GEOM, 9.0)
    assert mask[5, 50] and mask.sum() == 1
    # A cell echoing in two of every three looks: persistent once it echoed 7.5 s, near 7.5 / (2/3) s.
    bg = PolarBackground(CFG)
    state = []
    for t in np.arange(0.0, 40.0):
        state.append(bg.persistent(np.array([5]), np.array([50]), GEOM, t)[0])
        bg.update(echo if t % 3 != 2 else np.zeros(GEOM.shape, bool), GEOM, t)
    assert not any(state[:10]) and all(state[13:])


def test_target_moving_through_cells_is_not_learnt_but_a_stopped_one_is():
    """A cell-sized echo moving one cell per 2 s (echo 2 s in each cell) is never persistent; once it
    stops it is learnt after about T ln 2 = 42 s, as the module docstring says."""
    bg = PolarBackground(CFG)
    flagged, learnt = [], None
    for t in np.arange(0.0, 240.0):
        beam = min(int(t // 2), 70)  # moves until beam 70 (t = 140 s), then stays
        on = bg.persistent(np.array([10]), np.array([beam]), GEOM, t)[0]
        if t < 140:
            flagged.append(on)
        elif on and learnt is None:
            learnt = t - 140.0
        echo = np.zeros(GEOM.shape, bool)
        echo[10, beam] = True
        bg.update(echo, GEOM, t)
    assert not any(flagged)
    # T ln 2 = 41.6 s in steady state; a little sooner here, the cell's history being only 140 s long.
    assert 35.0 <= learnt <= 60.0 * math.log(2.0) + 2.0


def test_scanning_sectors_fall_on_the_same_cells_every_sweep():
    bg = PolarBackground(CFG)
    full = np.zeros((21, 360), bool)
    full[3, 200] = True
    for sweep in range(20):
        for k in range(36):
            g = SectorGeometry(angle_min=-math.pi + k * 10 * math.radians(1.0), angle_increment=math.radians(1.0),
                               n_beams=10, range_min=1.0, range_max=21.0, n_bins=21, ping_period=0.01, scan_time=5.0)
            bg.update(full[:, 10 * k:10 * k + 10], g, sweep * 5.0 + k * 0.1)
    g = SectorGeometry(angle_min=-math.pi + 200 * math.radians(1.0) - 2 * math.radians(1.0),
                       angle_increment=math.radians(1.0), n_beams=5, range_min=1.0, range_max=21.0, n_bins=21)
    assert bg.persistent_mask(g, 100.0)[3].tolist() == [False, False, True, False, False]
    assert bg.columns == 360  # one column per bearing of the turn


def test_margin_counts_neighbours_of_persistent_cells():
    bg = PolarBackground(StructureConfig(min_echo_time=0.0, margin=1))
    echo = np.zeros(GEOM.shape, bool)
    echo[5, 50] = True
    looks(bg, lambda t: echo, np.arange(0.0, 5.0))
    mask = bg.persistent_mask(GEOM, 5.0)
    assert mask[4:7, 49:52].all() and mask.sum() == 9


def test_grid_follows_the_sonar_and_keeps_the_history_it_still_covers():
    grid = GridBackground(CFG, 0.5)
    pts = (np.array([10.2, 3.0]), np.array([-4.1, 3.0]), np.array([True, False]))
    for t in np.arange(0.0, 20.0):
        grid.update([pts], (0.2 * t, 0.0), 15.0, t)   # the sonar drives 4 m in x
    assert grid.persistent(np.array([10.2, 10.4, 3.0]), np.array([-4.1, -4.2, 3.0]), 20.0).tolist() == \
        [True, True, False]
    grid.update([(np.array([0.0]), np.array([0.0]), np.array([False]))], (30.0, 0.0), 15.0, 21.0)
    assert not grid.persistent(np.array([10.2]), np.array([-4.1]), 21.0)[0]  # left the window: forgotten
    assert grid._n ** 2 <= CFG.max_map_cells


def test_grid_coarsens_to_its_memory_bound():
    grid = GridBackground(StructureConfig(max_map_cells=10_000), 0.01)
    grid.update([(np.array([1.0]), np.array([1.0]), np.array([True]))], (0.0, 0.0), 50.0, 0.0)
    assert grid.cell == pytest.approx(1.0) and grid._n ** 2 <= 10_404


def test_sector_background_adds_the_world_map_once_the_sonar_moves():
    bg = SectorBackground(StructureConfig(min_echo_time=5.0, margin=0))
    echo = np.zeros(GEOM.shape, bool)
    for t in np.arange(0.0, 10.0):
        bg.update(echo, GEOM, (0.0, 0.0, 0.0), t)
    assert not bg.moving and bg.grid is None
    bg.update(echo, GEOM, (1.0, 0.0, 0.0), 10.0)
    assert bg.moving and bg.grid is not None
    static = SectorBackground(StructureConfig(map='sensor'))
    static.update(echo, GEOM, (5.0, 0.0, 0.0), 0.0)
    assert static.grid is None


def test_polar_map_coarsens_range_to_its_memory_bound():
    g = SectorGeometry(angle_min=-0.5, angle_increment=0.01, n_beams=101, range_min=1.0, range_max=100.0,
                       n_bins=1000)
    bg = PolarBackground(StructureConfig(min_echo_time=0.0, margin=0, max_map_cells=30_000))
    echo = np.zeros(g.shape, bool)
    echo[501, 40] = True
    for t in range(5):
        bg.update(echo, g, float(t))
    assert bg.bins_per_cell == 4 and bg.columns == 101 and bg._s.size <= 30_000
    mask = bg.persistent_mask(g, 5.0)
    assert mask[500:504, 40].all() and mask.sum() == 4   # the map cell of bins 500-503

"""Static-structure rejection (core/structure.py): shape gates, the echo-frequency rule, both maps;
the maps' in-place and compiled looks against the rule applied cell by cell."""
from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest

from sonar_tracking.core import structure
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


# -- the maps' looks against the rule cell by cell -----------------------------------------------------

_NEW = (0.0, 0.0, 0.0, math.nan)    # S, W, time of the last look, time of the first look


class _Cells:
    """The echo-frequency rule on a dict of map cells, looked at a set of cells at a time."""

    def __init__(self, config: StructureConfig) -> None:
        self.config = config
        self.cells: dict = {}

    def look(self, echo: dict, t: float) -> None:
        """One look at the cells ``echo`` (cell -> whether it echoed)."""
        keys = list(echo)
        old = np.array([self.cells.get(k, _NEW) for k in keys]).reshape(-1, 4)
        s, w = old[:, 0].astype(np.float32), old[:, 1].astype(np.float32)
        t_last, t_first = old[:, 2].copy(), old[:, 3].copy()
        decay = structure._decay(t_last, t_first, np.arange(len(keys)), t, self.config.time_constant)
        s = s * decay + np.array([echo[k] for k in keys], bool)
        w = w * decay + 1.0
        for k, *values in zip(keys, s, w, t_last, t_first):
            self.cells[k] = tuple(values)

    def persistent(self, key, t: float) -> bool:
        s, w, t_last, t_first = self.cells[key]
        return bool(structure._persistent(np.float32(s), np.float32(w), t - t_first, t - t_last, self.config))


def _looks(seed: int, n: int):
    """``n`` look times with gaps of a frame, a few frames, and beyond the forgetting time (3 T)."""
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.choice([0.05, 0.05, 0.05, 0.1, 0.35, 9.5], size=n))


def test_the_sensor_maps_looks_are_the_rule_cell_by_cell():
    """Whole frames (the in-place look), partial views of the fan (a subset of its columns, also
    across the ring's seam) and range bins joined into map cells, with gaps and a restart after more
    than 3 T: every map cell's state and every persistence answer equal the rule's."""
    cfg = StructureConfig(enabled=True, time_constant=3.0, persistence=0.3, min_echo_time=0.4, margin=1,
                          max_map_cells=18_000)
    rng = np.random.default_rng(51)
    inc = 2 * math.pi / 120                                      # a ring of 120 bearings
    fan = SectorGeometry(angle_min=-40 * inc, angle_increment=inc, n_beams=80, range_min=1.0, range_max=60.0,
                         n_bins=300)                # 300 x 80 > 18 000: 2 bins a map cell, 120 columns fit
    static = rng.random(fan.shape) < 0.05
    bg, ref = PolarBackground(cfg), _Cells(cfg)
    k_bins, rows = 2, 150
    for step, t in enumerate(_looks(52, 90)):
        if step % 3 == 2:    # a partial view: 25 beams from a random start, sometimes past the fan's last
            first = int(rng.integers(-10, 100))
            g = SectorGeometry(angle_min=fan.angle_min + first * inc, angle_increment=inc, n_beams=25,
                               range_min=1.0, range_max=60.0, n_bins=300)
            echo = rng.random(g.shape) < 0.03
        else:
            g, echo = fan, static | (rng.random(fan.shape) < 0.03)
        slots = np.rint((g.bearings() - fan.angle_min) / inc).astype(int) % 120
        r, b = np.nonzero(rng.random(g.shape) < 0.01)
        mine = bg.persistent(r, b, g, float(t))
        theirs = [any(0 <= rr // k_bins + dr < rows and (rr // k_bins + dr, (slots[bb] + db) % 120) in ref.cells
                      and ref.persistent((rr // k_bins + dr, (slots[bb] + db) % 120), float(t))
                      for dr in (-1, 0, 1) for db in (-1, 0, 1)) for rr, bb in zip(r, b)]
        assert mine.tolist() == theirs, step
        bg.update(echo, g, float(t))
        joined = echo.reshape(rows, k_bins, -1).any(axis=1)
        ref.look({(row, int(slot)): bool(joined[row, j]) for j, slot in enumerate(slots) for row in range(rows)},
                 float(t))
    assert bg.bins_per_cell == k_bins
    for (row, slot), (s, w, t_last, t_first) in ref.cells.items():
        col = bg._col[slot]
        assert (bg._s[row, col], bg._w[col], bg._t_last[col]) == (s, w, t_last), (row, slot)
        assert bg._t_first[col] == t_first


def _grid_window(grid_cell: float, config: StructureConfig, x: float, y: float, reach: float):
    """Cell size, first global cell and size of the world window around ``(x, y)`` (GridBackground)."""
    cell = max(grid_cell, 2.0 * reach / math.sqrt(config.max_map_cells))
    n = int(math.ceil(2.0 * reach / cell)) + 2
    return cell, int(math.floor((x - reach) / cell)) - 1, int(math.floor((y - reach) / cell)) - 1, n


def test_the_world_maps_sector_looks_are_the_rule_cell_by_cell():
    """A sector seen from a pose changing every look (moves of a fraction of a cell, a jump beyond
    the window, a longer range that resizes the window), with gaps and a restart after more than 3 T:
    the cells that hold a sector cell's world position are looked at, those of its echoing cells
    echo, cells that leave the window are forgotten, and every state and persistence answer equals
    the rule's."""
    cfg = StructureConfig(enabled=True, time_constant=3.0, persistence=0.3, min_echo_time=0.4, margin=1)
    rng = np.random.default_rng(61)
    near = SectorGeometry(angle_min=-0.6, angle_increment=0.02, n_beams=61, range_min=0.5, range_max=12.0,
                          n_bins=80)
    far = SectorGeometry(angle_min=-0.6, angle_increment=0.02, n_beams=61, range_min=0.5, range_max=16.0,
                         n_bins=80)
    grid, ref = GridBackground(cfg, 0.25), _Cells(cfg)
    window = None
    for step, t in enumerate(_looks(62, 80)):
        g = far if 40 <= step < 55 else near
        pose = (0.04 * step, -0.03 * step, 0.01 * step) if step != 30 else (90.0, 40.0, 2.0)
        reach = g.range_max + g.range_resolution
        cell, i0, j0, n = _grid_window(0.25, cfg, pose[0], pose[1], reach)
        if window is not None and window[0] != cell:
            ref.cells.clear()
        window = (cell, i0, j0, n)
        ref.cells = {k: v for k, v in ref.cells.items() if i0 <= k[0] < i0 + n and j0 <= k[1] < j0 + n}
        rows, beams = (v.ravel() for v in np.indices(g.shape))
        x, y = structure._sector_points(g, pose, rows, beams)
        gi, gj = np.floor(x / cell).astype(int), np.floor(y / cell).astype(int)
        echo = rng.random(g.shape) < 0.02
        echo[20:30, 10:14] = True                 # something static in the sensor frame
        if grid._n:
            probe = rng.integers(0, len(x), 300)
            mine = grid.persistent(x[probe], y[probe], float(t))
            theirs = [any((gi[p] + di, gj[p] + dj) in ref.cells and ref.persistent((gi[p] + di, gj[p] + dj), float(t))
                          for di in (-1, 0, 1) for dj in (-1, 0, 1)) for p in probe]
            assert mine.tolist() == theirs, step
        grid.update_sector(echo, g, pose, reach, float(t))
        inside = (gi >= i0) & (gi < i0 + n) & (gj >= j0) & (gj < j0 + n)
        seen: dict = {}
        for a, b, e in zip(gi[inside], gj[inside], echo.ravel()[inside]):
            seen[(int(a), int(b))] = seen.get((int(a), int(b)), False) or bool(e)
        ref.look(seen, float(t))
        assert (grid.cell, grid._i0, grid._j0, grid._n) == window
    slots = {(i, j): ((i % n) * n + j % n) for i in range(i0, i0 + n) for j in range(j0, j0 + n)}
    for key, k in slots.items():
        assert (grid._s[k], grid._w[k], grid._t_last[k]) == ref.cells.get(key, _NEW)[:3], key
        assert np.array_equal(grid._t_first[k], ref.cells.get(key, _NEW)[3], equal_nan=True)


def test_a_look_with_more_previous_look_times_than_the_compiled_pass_takes_is_the_same(monkeypatch):
    """Beyond the distinct previous look times the compiled look handles, the array form of the rule
    does the look: the same states."""
    cfg = StructureConfig(enabled=True, time_constant=3.0, persistence=0.3, min_echo_time=0.4, margin=0)
    g = SectorGeometry(angle_min=-0.6, angle_increment=0.02, n_beams=61, range_min=0.5, range_max=12.0, n_bins=80)
    states = []
    for limit in (structure._LAST_LOOKS, 2):
        monkeypatch.setattr(structure, '_LAST_LOOKS', limit)
        grid = GridBackground(cfg, 0.25)
        rng = np.random.default_rng(71)
        for t in _looks(72, 30):
            pose = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-0.3, 0.3)))
            grid.update_sector(rng.random(g.shape) < 0.05, g, pose, 12.5, float(t))
        states.append([getattr(grid, name).copy() for name in ('_s', '_w', '_t_last', '_t_first')])
    for a, b in zip(*states):
        assert np.array_equal(a, b, equal_nan=True)


def test_an_imaging_frame_is_learnt_without_frame_sized_temporaries():
    """A 512-beam x 1000-bin frame: the sensor map looks in place (a few kilobytes besides the map),
    and the world map of a moving sonar takes its two flags per window cell, nothing per sector
    cell (the sector's world positions are 16 bytes a cell), even when the window moves."""
    g = SectorGeometry(angle_min=-1.13, angle_increment=0.0044, n_beams=512, range_min=0.1, range_max=30.0,
                       n_bins=1000)
    rng = np.random.default_rng(81)
    echo = rng.random(g.shape) < 0.001
    polar = PolarBackground(StructureConfig(enabled=True))
    polar.update(echo, g, 0.0)
    tracemalloc.start()
    try:
        polar.update(echo, g, 0.05)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2 ** 16, peak
    bg = SectorBackground(StructureConfig(enabled=True, map='world'))
    bg.update(echo, g, (0.0, 0.0, 0.0), 0.0)
    flags = 2 * bg.grid._n ** 2
    tracemalloc.start()
    try:
        bg.update(echo, g, (0.5, 0.2, 0.01), 0.05)     # the window moves by several cells
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < flags + 2 ** 18, (peak, flags)

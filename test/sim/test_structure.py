"""Artefacts of real echoes in the simulator: walls, seabed band, ringdown, piles, 8-bit dB output with
exact zeros, a clockwise head; existing scenarios untouched; a run is a function of its seed."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.intensity import decode, encode_db
from sonar_tracking.sim import SeaKingConfig, SeaKingSonar, SimConfig, Simulator
from sonar_tracking.sim.scene import Scene
from sonar_tracking.sim.structure import HARBOUR_PILES


def sweep_image(cfg: SimConfig, seed: int, sweeps: int) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Decoded linear amplitudes of ``sweeps`` full sector-mode passes, each as bins x head positions
    in increasing bearing; plus the ranges and bearings [rad] of the positions."""
    sim = Simulator(cfg, np.random.default_rng(seed))
    s = cfg.seaking
    bearings = np.radians(s.scan_min_deg + np.arange(s.n_positions) * s.step_deg)
    images, current = [], np.full((s.n_bins, s.n_positions), np.nan)
    while len(images) < sweeps:
        sector = sim.next_sector()
        g = sector.geometry
        cols = np.rint((np.degrees(g.bearings()) - s.scan_min_deg) / s.step_deg).astype(int)
        current[:, cols] = decode(sector.amplitudes, cfg.output.coding, db_span=cfg.output.db_span,
                                  full_scale=255.0 if sector.amplitudes.dtype == np.uint8 else None)
        if sector.end_of_sweep:
            images.append(current.copy())
    return images, sim.sensor.ranges, bearings


def db(x):
    return 10.0 * np.log10(x)


@pytest.fixture(scope='module')
def tank():
    cfg = SimConfig.for_scenario('structure_only', 'seaking675', **{'seaking.n_bins': 300})
    images, ranges, bearings = sweep_image(cfg, 11, 6)
    return cfg, images[1:], ranges, bearings  # the first pass starts mid-sector


def test_encode_db_inverts_decode_with_zeros_below_the_gain_floor():
    a = np.array([0.0, 0.3, 0.69, 0.7, 1.0, 7.0, 70.0, 7e2, 7e3, 1e9, np.nan, -1.0])
    counts = encode_db(a, 60.0, 255, reference=0.7)
    assert counts.dtype == np.uint8
    assert list(counts[:3]) == [0, 0, 0] and counts[3] == 1 and counts[-3] == 255
    assert counts[-2] == 0 and counts[-1] == 0
    back = decode(counts, 'db', db_span=60.0, full_scale=255.0) * 0.7
    ok = (counts > 0) & (counts < 255)
    half_count_db = 0.5 * 60.0 / 255
    assert np.all(np.abs(db(back[ok] / a[ok]) / 2) <= half_count_db / 2 + 1e-9)
    assert encode_db(np.array([1.0, 1e3]), 60.0, 65535).dtype == np.uint16


def test_existing_scenarios_are_what_they_were_with_the_artefacts_off():
    """A structured scenario with structure and coding switched off gives its plain scenario's sectors."""
    for name, preset in (('fls8', 'seaking675'), ('scenario2', 'harbour')):
        plain = Simulator(SimConfig.for_scenario(name, preset), np.random.default_rng(4))
        off = Simulator(SimConfig.for_scenario(f'{name}_structured', preset, **{
            'structure.kind': 'none', 'output.coding': 'linear_amplitude'}), np.random.default_rng(4))
        for _ in range(30):
            a, b = plain.next_sector(), off.next_sector()
            assert a.amplitudes.dtype == np.float32
            np.testing.assert_array_equal(a.amplitudes, b.amplitudes)
            assert a.geometry == b.geometry and a.stamp == b.stamp
        structured = Simulator(SimConfig.for_scenario(f'{name}_structured', preset), np.random.default_rng(4))
        for t in (1.0, 20.0, 45.0):  # the same targets on the same paths
            np.testing.assert_array_equal(plain.truth(t)[1], structured.truth(t)[1])


def test_a_run_is_a_function_of_its_seed():
    for name, preset in (('fls8_structured', 'seaking325'), ('structure_only', 'harbour')):
        runs = [Simulator(SimConfig.for_scenario(name, preset), np.random.default_rng(seed)) for seed in (5, 5, 6)]
        for _ in range(12):
            a, b, c = (r.next_sector().amplitudes for r in runs)
            assert a.dtype == np.uint8
            np.testing.assert_array_equal(a, b)
        assert not np.array_equal(a, c)


def test_tank_walls_are_bright_and_static(tank):
    cfg, images, ranges, bearings = tank
    # Where the walls are, by bearing: side walls y = +/-8 m, back wall x = 28.5 m.
    r_side = 8.0 / np.maximum(np.abs(np.sin(bearings)), 1e-9)
    r_back = 28.5 / np.cos(bearings)
    wall_r = np.minimum(r_side, r_back)
    seen = wall_r < ranges[-1] - 0.3
    stack = np.stack(images)  # sweeps x bins x beams
    mean = stack.mean(axis=0)
    background = np.median(mean[(ranges > 10.0) & (ranges < 20.0)][:, np.abs(bearings) < math.radians(10)])
    near = np.abs(ranges[:, None] - wall_r[None, :]) < 0.25
    wall_peak = np.where(near, mean, 0.0).max(axis=0)[seen]
    assert seen.sum() > 60
    assert np.median(db(wall_peak / background)) > 12.0
    assert db(wall_peak / background).min() > 5.0  # no gap along the walls
    # Static: the wall's per-cell level repeats from sweep to sweep (gamma fluctuation, shape 8).
    cells = near[:, seen]
    per_sweep = stack[:, :, seen][:, cells]
    first, second = per_sweep[: len(images) // 2].mean(axis=0), per_sweep[len(images) // 2:].mean(axis=0)
    bright = first > 10 * background
    assert np.corrcoef(np.log(first[bright]), np.log(second[bright] + 1e-9))[0, 1] > 0.8


def test_tank_seabed_band_and_ringdown(tank):
    cfg, images, ranges, bearings = tank
    stack = np.stack(images)
    # Means (medians of counts with half the cells 0 are 0), on the beams clear of the side walls.
    per_bin = stack[:, :, np.abs(bearings) < math.radians(12)].mean(axis=(0, 2))
    background = per_bin[(ranges > 10.0) & (ranges < 20.0)].mean()
    band = (ranges > 3.5) & (ranges < 5.5)
    assert db(per_bin[band] / background).min() > 4.0
    assert abs(db(per_bin[(ranges > 7.0) & (ranges < 9.0)].mean() / background)) < 1.0
    # Ringdown: the first bins are bright on every beam in every sweep and fall off with range.
    first = stack[:, 0, :]
    assert db(first.min() / background) > 20.0
    ring = stack.mean(axis=(0, 2))[ranges < 1.2]
    assert np.all(np.diff(ring[:12]) < 0)
    assert db(ring[0] / ring[11]) > 10.0


def test_zeros_in_db_output(tank):
    """8-bit dB output: about half of the open-water cells are exact zeros (gain floor 0.7, lam 1)."""
    cfg, images, ranges, bearings = tank
    stack = np.stack(images)
    water = stack[:, (ranges > 9.0) & (ranges < 20.0)][:, :, np.abs(bearings) < math.radians(10)]
    zeros = (water == 0).mean()
    # Exponential reverberation of mean 1 plus weak noise: P(a < 0.7 * 10^(-0.118/20)) is about 0.49.
    assert 0.42 < zeros < 0.56
    per_bin = (water == 0).mean(axis=(0, 2))
    assert per_bin.min() > 0.3 and per_bin.max() < 0.7
    assert (stack[:, ranges < 0.5] == 0).mean() == 0.0  # ringdown never drops out


def test_harbour_piles_walls_and_band_are_static():
    cfg = SimConfig.for_scenario('structure_only', 'harbour')
    sim = Simulator(cfg, np.random.default_rng(8))
    sectors = [sim.next_sector() for _ in range(20)]
    scans = np.stack([decode(s.amplitudes, 'db', db_span=60.0, full_scale=255.0) for s in sectors])
    sonar = sim.sensor
    i, j, inside, _, _ = sonar.cell_of(np.array(HARBOUR_PILES), sectors[0].pose)
    assert inside.all()
    background = np.median(scans[:, 20:60, 5:40])
    pile = scans[:, i, j]  # scans x piles
    assert db(np.median(pile) / background) > 15.0
    assert (pile > 10 * background).mean() > 0.9  # every pile, nearly every scan
    # Quay wall at x = 1150: the cells it crosses are bright in the mean.
    mean = scans.mean(axis=0)
    ranges, bearings = sonar.geometry.ranges(), sonar.geometry.bearings()
    quay_r = (1150.0 + 2000.0) / np.cos(bearings)
    rows = np.floor((quay_r - (ranges[0] - 0.5 * cfg.harbour.cell_depth)) / cfg.harbour.cell_depth).astype(int)
    ok = rows < len(ranges)
    assert db(np.median(mean[rows[ok], np.flatnonzero(ok)]) / background) > 10.0
    # Breakwater along bearing 21 deg: the column holding it is bright from 1900 m out.
    col = int(np.argmin(np.abs(bearings - math.radians(21.0))))
    assert db(np.median(mean[5:80, col]) / background) > 8.0
    band = (ranges > 1920) & (ranges < 1980)
    assert db(np.median(mean[band]) / background) > 4.0


def test_structure_must_fit_the_sensor():
    with pytest.raises(ConfigError, match='structure.kind'):
        SimConfig.for_scenario('fls1', **{'structure.kind': 'harbour'})
    with pytest.raises(ConfigError, match='structure.kind'):
        SimConfig.for_scenario('scenario1', **{'structure.kind': 'tank'})
    with pytest.raises(ConfigError, match='seabed_range_max'):
        SimConfig.for_scenario('fls1', **{'structure.seabed_range_max': 2.0})


@pytest.mark.parametrize('continuous', [True, False])
def test_clockwise_head(continuous):
    span = (-180.0, 180.0) if continuous else (-45.0, 45.0)
    cfg = SeaKingConfig(range_max=20.0, n_bins=50, step_deg=3.0, scan_min_deg=span[0], scan_max_deg=span[1],
                        turn='cw')
    sonar = SeaKingSonar(cfg, sector_size=7)
    rng = np.random.default_rng(0)
    sectors = [sonar.next_sector(Scene([], lam=1.0), rng) for _ in range(8)]
    first = sectors[0]
    assert first.geometry.ping_period < 0  # column 0 was pinged last
    # It starts at the left limit, turning right.
    assert math.degrees(first.geometry.angle_max) == pytest.approx(span[0] + (cfg.n_positions - 1) * 3.0)
    stamps = [s.stamp for s in sectors]
    assert np.all(np.diff(stamps) > 0)
    if continuous:
        # Turning clockwise all the way: every sector further right, until the turn wraps.
        mins = [math.degrees(s.geometry.angle_min) for s in sectors]
        assert np.all(np.diff(mins) < 0)
        assert all(s.geometry.ping_period < 0 for s in sectors)
    # Each column's ping time: stamp + column * ping_period, so the earliest ping is column n - 1.
    g = first.geometry
    times = first.stamp + np.arange(g.n_beams) * g.ping_period
    assert times.argmin() == g.n_beams - 1
    assert times.min() == pytest.approx(cfg.ping_period)
    ccw = SeaKingSonar(dataclasses.replace(cfg, turn='ccw'), sector_size=7).next_sector(Scene([], lam=1.0), rng)
    assert ccw.geometry.ping_period > 0

"""Simulator facade and scenario presets: determinism, compatibility, the scenarios' geometry."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.sim import SCENARIOS, SimConfig, Simulator


def sectors(config, seed, n):
    sim = Simulator(config, np.random.default_rng(seed))
    return [sim.next_sector() for _ in range(n)], sim


def test_same_seed_same_sectors_other_seed_other_sectors():
    cfg = SimConfig.for_scenario('fls9')
    a, _ = sectors(cfg, 4, 20)
    b, _ = sectors(cfg, 4, 20)
    c, _ = sectors(cfg, 5, 20)
    assert all(np.array_equal(x.amplitudes, y.amplitudes) and x.stamp == y.stamp for x, y in zip(a, b))
    assert not np.array_equal(a[3].amplitudes, c[3].amplitudes)


def test_a_run_is_a_function_of_the_seed_not_of_the_generator_object():
    # Two simulators from ONE generator object: the streams come from its seed, not from spawning
    # (which would advance the shared SeedSequence and give the second simulator other sectors).
    cfg = SimConfig.for_scenario('fls9')
    rng = np.random.default_rng(4)
    first, second = Simulator(cfg, rng), Simulator(cfg, rng)
    fresh, _ = sectors(cfg, 4, 3)
    for want in fresh:
        a, b = first.next_sector(), second.next_sector()
        assert np.array_equal(a.amplitudes, want.amplitudes) and np.array_equal(b.amplitudes, want.amplitudes)
    assert rng.bit_generator.seed_seq.n_children_spawned == 0


def test_sector_grouping_does_not_move_the_targets():
    _, s1 = sectors(SimConfig.for_scenario('fls10', sector_size=5), 1, 3)
    _, s2 = sectors(SimConfig.for_scenario('fls10', sector_size=50), 1, 3)
    for t in (0.0, 17.3, 42.0):
        assert np.array_equal(s1.truth(t)[1], s2.truth(t)[1])


def test_scenario_needs_its_sensor():
    with pytest.raises(ConfigError, match='runs on harbour'):
        SimConfig.for_scenario('scenario1', 'seaking675')
    with pytest.raises(ConfigError, match='unknown scenario'):
        SimConfig.for_scenario('scenario9')
    with pytest.raises(ConfigError, match='unknown sensor preset'):
        SimConfig.for_scenario('fls1', 'seaking999')


def test_scenarios_end_after_their_duration():
    for name, n in (('scenario1', 50), ('scenario2', 100)):
        sim = Simulator(SimConfig.for_scenario(name), np.random.default_rng(0))
        count = sum(1 for _ in iter(sim.next_sector, None))
        assert count == n


def min_distance(sim, a, b, t_end):
    ts = np.linspace(0, t_end, 400)
    return min(np.hypot(*(sim.truth(t)[1][a, :2] - sim.truth(t)[1][b, :2])) for t in ts)


@pytest.mark.parametrize('n', [8, 9, 10, 11])
def test_crossing_situations_cross(n):
    sim = Simulator(SimConfig.for_scenario(f'fls{n}'), np.random.default_rng(n))
    assert min_distance(sim, 0, 1, SCENARIOS[f'fls{n}'].duration) < 1.5
    # Opposite directions along x.
    v = sim.truth(10.0)[1][:, 2]
    assert v[0] * v[1] < 0


@pytest.mark.parametrize('n', [5, 6, 7, 12])
def test_same_direction_situations_stay_apart(n):
    sim = Simulator(SimConfig.for_scenario(f'fls{n}'), np.random.default_rng(n))
    k = len(sim.scene.targets)
    for a, b in itertools.combinations(range(k), 2):
        assert min_distance(sim, a, b, SCENARIOS[f'fls{n}'].duration) > 1.0


def test_situation_targets_are_the_papers():
    shapes = {n: sorted(t.shape.name for t in Simulator(SimConfig.for_scenario(f'fls{n}'),
                                                         np.random.default_rng(0)).scene.targets)
              for n in range(1, 15)}
    assert shapes[1] == ['pontoon'] and shapes[4] == ['reflector'] and shapes[7] == ['reflector', 'sphere']
    assert shapes[10] == ['cube', 'pontoon'] and shapes[13] == ['cube', 'prism', 'reflector']
    sim = Simulator(SimConfig.for_scenario('fls14'), np.random.default_rng(0))
    assert np.hypot(*sim.truth(30.0)[1][0, 2:]) < 0.1  # does not move


def test_sea_trial_platform_moves_at_half_a_metre_per_second():
    sim = Simulator(SimConfig.for_scenario('sea_trial'), np.random.default_rng(0))
    x, y, yaw, vx, vy = sim.scene.platform_pose(20.0)
    assert (x, vx, vy) == pytest.approx((10.0, 0.5, 0.0))
    speeds = [np.hypot(*sim.truth(t)[1][:, 2:].T) for t in np.linspace(0, 160, 50)]
    assert 0.4 < np.mean(speeds) < 1.0

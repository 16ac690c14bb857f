"""SeaKing head and echo model (FLS §2, Table 1): timing, sweeps, beams, TVG, multipath, aspect."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from sonar_tracking.core.config import ConfigError
from sonar_tracking.sim import Scene, SeaKingConfig, SeaKingSonar, SimConfig, Target
from sonar_tracking.sim.motion import StaticTrajectory
from sonar_tracking.sim.shapes import shape


def pings(sectors):
    """(time, bearing_deg) of every ping, from the sectors' stamps, geometry and column order."""
    out = []
    for s in sectors:
        g = s.geometry
        for k, b in enumerate(g.bearings()):
            out.append((s.stamp + k * g.ping_period, math.degrees(b)))
    return sorted(out)


def run(sonar, n_sectors, scene=None):
    scene = scene or Scene([], lam=1.0)
    rng = np.random.default_rng(0)
    return [sonar.next_sector(scene, rng) for _ in range(n_sectors)]


def test_ping_period_sweep_time_and_sector_reversal():
    cfg = SeaKingConfig(range_max=30.0, n_bins=100, step_deg=0.9, scan_min_deg=-45.0, scan_max_deg=45.0)
    assert cfg.ping_period == pytest.approx(2 * 30.0 / 1500.0 + 0.01)
    assert cfg.n_positions == 101 and cfg.sweep_time == pytest.approx(100 * cfg.ping_period)
    sectors = run(SeaKingSonar(cfg, sector_size=7), 60)
    p = np.array(pings(sectors))
    assert np.diff(p[:, 0]) == pytest.approx(cfg.ping_period)
    b = p[:, 1]
    # Back and forth between the limits; each limit pinged once per reversal.
    expected = np.concatenate([np.arange(101), np.arange(99, -1, -1), np.arange(1, 101), np.arange(99, -1, -1)])
    n = min(len(b), len(expected))
    assert b[:n] == pytest.approx(-45.0 + 0.9 * expected[:n])
    # Reversals every sweep_time; sectors end there.
    t_right = p[np.isclose(b, -45.0), 0]
    assert np.diff(t_right) == pytest.approx(2 * cfg.sweep_time)
    ends = [s for s in sectors if s.end_of_sweep]
    assert [round(math.degrees(s.geometry.angle_max if s.geometry.ping_period > 0 else s.geometry.angle_min), 6)
            for s in ends][:3] == [45.0, -45.0, 45.0]
    for s in sectors:
        assert s.geometry.n_beams <= 7
        assert s.geometry.ping_period == pytest.approx(cfg.ping_period * (1 if s.geometry.n_beams == 1 or
                                                                            s.geometry.ping_period > 0 else -1))


def test_continuous_mode_turns_and_wraps():
    cfg = SeaKingConfig(range_max=50.0, n_bins=64, step_deg=1.8, scan_min_deg=-180.0, scan_max_deg=180.0)
    assert cfg.continuous and cfg.n_positions == 200
    sectors = run(SeaKingSonar(cfg, sector_size=64), 8)
    assert [s.geometry.n_beams for s in sectors] == [64, 64, 64, 8, 64, 64, 64, 8]
    assert [s.end_of_sweep for s in sectors] == [False, False, False, True] * 2
    b = np.array(pings(sectors))[:, 1]
    assert np.diff(b[:200]) == pytest.approx(1.8)
    assert b[200] == pytest.approx(-180.0)
    assert all(s.geometry.ping_period > 0 for s in sectors)


@pytest.mark.parametrize('changes, match', [
    ({'range_max': 150.0}, 'maximum of 100 m'),
    ({'frequency_khz': 325.0, 'range_max': 301.0}, 'must be <= 300'),
    ({'n_bins': 0}, 'n_bins = 0 must be >= 2'),
    ({'range_max': -5.0}, 'range_max = -5.0 must be >= 0.5'),
    ({'scan_min_deg': 10.0, 'scan_max_deg': 10.0}, 'must be in \\(0, 360\\]'),
    ({'step_deg': 15.0, 'scan_min_deg': 0.0, 'scan_max_deg': 10.0}, 'larger than the sector span'),
    ({'frequency_khz': 500.0}, 'not one of'),
])
def test_bad_settings_refused_with_reason(changes, match):
    with pytest.raises(ConfigError, match=match):
        SeaKingConfig(**changes)


def test_presets_follow_table1():
    a = SimConfig.for_scenario('fls1', 'seaking675')
    b = SimConfig.for_scenario('fls1', 'seaking325')
    assert (a.seaking.beam_width_deg, a.seaking.vertical_beam_width_deg) == (1.5, 40.0)
    assert (b.seaking.beam_width_deg, b.seaking.vertical_beam_width_deg) == (3.0, 20.0)
    with pytest.raises(ConfigError, match='maximum of 100 m'):
        SimConfig.for_scenario('fls1', 'seaking675', **{'seaking.range_max': 200.0})
    assert SimConfig.for_scenario('fls1', 'seaking325', **{'seaking.range_max': 200.0}).seaking.range_max == 200.0


def test_tvg_makes_reverberation_flat_and_noise_grow():
    cfg = SeaKingConfig(range_max=50.0, n_bins=500, noise_db=-150.0)
    sonar = SeaKingSonar(cfg, sector_size=101)
    amps = np.concatenate([s.amplitudes for s in run(sonar, 30, Scene([], lam=1.25))], axis=1)
    bands = amps.reshape(10, 50, -1).mean(axis=(1, 2))
    assert bands == pytest.approx(0.8, rel=0.03)
    # Noise before speckle: (r / r_ref)^(tvg/10) * 10^(2 a (r - r_ref) / 10) re the reference level.
    r = sonar.ranges
    expected = 10 ** (cfg.noise_db / 10) * (r / 10.0) ** 3 * 10 ** (0.4 * (r - 10.0) / 10)
    assert sonar.noise_profile == pytest.approx(expected)
    loud = SeaKingSonar(SeaKingConfig(range_max=50.0, n_bins=500, noise_db=0.0), sector_size=101)
    far = np.concatenate([s.amplitudes for s in run(loud, 10, Scene([], lam=1.0))], axis=1)[-50:].mean()
    assert far == pytest.approx(1.0 + loud.noise_profile[-50:].mean(), rel=0.05)


def point_echo(sonar, x, y, depth=0.0, snr=30.0, name='point'):
    scene = Scene([Target(1, StaticTrajectory(x, y), shape(name), snr)], lam=1.0, depth=depth)
    plan = sonar.plan()
    _, echo, _ = sonar.render_mean(scene, plan)
    return plan, echo


def test_point_echo_spreads_over_adjacent_steps_with_the_beam_pattern():
    cfg = SeaKingConfig(range_max=20.0, n_bins=400, step_deg=0.45, scan_min_deg=-9.9, scan_max_deg=9.9,
                        pulse_length=0.0)
    plan, echo = point_echo(SeaKingSonar(cfg, sector_size=1000), 10.0, 0.0)
    per_ping = echo.sum(axis=0)
    off = plan.bearings
    expected = np.exp(-4 * math.log(2) * (off / math.radians(1.5)) ** 2)
    assert per_ping / per_ping.max() == pytest.approx(expected, abs=1e-9)
    assert (per_ping > 0.5 * per_ping.max()).sum() == 3  # beam 1.5 deg over 0.45 deg steps
    # Target echo after TVG: SNR at the reference range (10 m), beam centre.
    assert per_ping.max() == pytest.approx(10 ** 3.0, rel=1e-6)


def test_echo_falls_with_range_as_tvg_leaves_it():
    cfg = SeaKingConfig(range_max=40.0, n_bins=400, step_deg=0.45, scan_min_deg=-10.0, scan_max_deg=10.0,
                        pulse_length=0.0, absorption_db_per_m=0.2)
    near = point_echo(SeaKingSonar(cfg, sector_size=1000), 10.0, 0.0)[1].sum()
    far = point_echo(SeaKingSonar(cfg, sector_size=1000), 30.0, 0.0)[1].sum()
    assert far / near == pytest.approx(10.0 / 30.0, rel=1e-6)  # 40 log r spreading, 30 log r TVG


def test_surface_multipath_ghost_behind_the_target():
    cfg = SeaKingConfig(range_max=20.0, n_bins=800, step_deg=0.45, scan_min_deg=-5.0, scan_max_deg=5.0,
                        pulse_length=0.0, ghost_db=-8.0, vertical_beam_width_deg=40.0)
    sonar = SeaKingSonar(cfg, sector_size=1000)
    r, d = 8.0, 1.5
    _, echo = point_echo(sonar, r, 0.0, depth=d)
    profile = echo.sum(axis=1)
    bins = sonar.ranges
    direct = profile[np.abs(bins - r) < 0.1].sum()
    r_ghost = 0.5 * (r + math.sqrt(r * r + 4 * d * d))
    ghost = profile[np.abs(bins - r_ghost) < 0.1].sum()
    elev = math.atan2(2 * d, r)
    assert ghost / direct == pytest.approx(10 ** -0.8 * math.exp(-4 * math.log(2) * (elev / math.radians(40.0)) ** 2),
                                           rel=1e-6)


def test_one_target_can_show_as_several_unconnected_regions():
    cfg = SeaKingConfig(range_max=15.0, n_bins=600, step_deg=0.45, scan_min_deg=-20.0, scan_max_deg=20.0)

    def regions(name, yaw_deg, depth):
        sonar = SeaKingSonar(cfg, sector_size=1000)
        scene = Scene([Target(1, StaticTrajectory(8.0, 0.0, math.radians(yaw_deg)), shape(name), 30.0)],
                      lam=1.0, depth=depth)
        _, echo, _ = sonar.render_mean(scene, sonar.plan())
        return ndimage.label(echo > echo.max() * 10 ** -1.3)[1]

    counts = {(n, y): regions(n, y, 1.5) for n in ('cube', 'pontoon', 'prism') for y in range(0, 91, 15)}
    assert max(counts.values()) >= 3 and sum(c >= 2 for c in counts.values()) >= 10
    assert regions('sphere', 0, 0.0) == 1


def test_aspect_changes_the_echo_of_flat_faces_but_not_of_a_sphere():
    def peak(name, yaw_deg):
        cfg = SeaKingConfig(range_max=15.0, n_bins=600, step_deg=0.45, scan_min_deg=-20.0, scan_max_deg=20.0)
        sonar = SeaKingSonar(cfg, sector_size=1000)
        scene = Scene([Target(1, StaticTrajectory(8.0, 0.0, math.radians(yaw_deg)), shape(name), 30.0)], lam=1.0,
                      depth=0.0)
        return sonar.render_mean(scene, sonar.plan())[1].sum()

    assert peak('cube', 0) > 3 * peak('cube', 45)
    assert peak('pontoon', 0) > 3 * peak('pontoon', 45)
    assert peak('sphere', 0) == pytest.approx(peak('sphere', 37), rel=0.05)

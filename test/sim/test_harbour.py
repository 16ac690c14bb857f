"""Harbour sonar (ESC §2, §5): cell geometry, measurement spread, clutter regions, scan timing."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.sim import HarbourConfig, HarbourSonar, Scene, SimConfig, Simulator, Target
from sonar_tracking.sim.motion import StaticTrajectory
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY


def test_cells_are_2sqrt3_sigma():
    cfg = HarbourConfig()
    g = cfg.geometry()
    assert g.range_resolution == pytest.approx(2 * math.sqrt(3) * 5.0)
    assert g.angle_increment == pytest.approx(2 * math.sqrt(3) * math.radians(0.1))
    assert g.ping_period == 0.0 and g.scan_time == 1.0
    assert g.range_min - g.range_resolution / 2 == pytest.approx(cfg.range_min)


def test_detected_cell_centres_spread_like_the_papers_noise():
    """Targets uniformly placed; the strongest cell's centre minus the truth has std sigma_r, sigma_theta."""
    sonar = HarbourSonar(HarbourConfig())
    g = sonar.geometry
    rng = np.random.default_rng(11)
    x0, y0 = HARBOUR_SONAR_XY
    dr, db = [], []
    for _ in range(1500):
        r = rng.uniform(2000.0, 3000.0)
        b = rng.uniform(math.radians(2.0), math.radians(18.0))
        scene = Scene([Target(1, StaticTrajectory(x0 + r * math.cos(b), y0 + r * math.sin(b)), snr_db=60.0)],
                      StaticTrajectory(x0, y0), lam=1.2)
        a = sonar.next_sector(scene, rng).amplitudes
        i, j = np.unravel_index(np.argmax(a), a.shape)
        dr.append(g.ranges()[i] - r)
        db.append(g.bearings()[j] - b)
    assert np.std(dr) == pytest.approx(5.0, rel=0.10)
    assert np.degrees(np.std(db)) == pytest.approx(0.1, rel=0.10)
    assert abs(np.mean(dr)) < 0.5 and abs(np.degrees(np.mean(db))) < 0.01


def test_scenario2_regions_and_timing():
    sim = Simulator(SimConfig.for_scenario('scenario2'), np.random.default_rng(0))
    y50 = sim.truth(50.0)[1][0, 1]
    pose = sim.scene.platform_pose(0.0)[:3]
    cells = sim.sensor.cell_centres(pose)
    lam = sim.scene.lam_at(cells)
    assert set(np.unique(lam)) == {0.8, 1.6}
    assert np.all((lam == 0.8) == (cells[..., 1] > y50))
    stamps = []
    while (s := sim.next_sector()) is not None:
        stamps.append(s.stamp)
    assert stamps == pytest.approx(list(np.arange(1.0, 101.0)))


def test_window_must_hold_a_cell():
    with pytest.raises(ConfigError, match='at least one cell'):
        HarbourConfig(range_min=2000.0, range_max=2010.0)

"""Target motion: CV/CTR segments (ESC eqs. 3-4, Table 2) and towed targets (FLS §5)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.sim.motion import DraggedTrajectory, ScriptedTrajectory, Segment
from sonar_tracking.sim.presets import SCENARIO2_SEGMENTS


def f_ctr(omega: float, dt: float) -> np.ndarray:
    """ESC eq. (4)."""
    s, c = math.sin(omega * dt), math.cos(omega * dt)
    return np.array([[1, 0, s / omega, -(1 - c) / omega], [0, 1, (1 - c) / omega, s / omega],
                     [0, 0, c, -s], [0, 0, s, c]])


def test_ctr_segment_is_eq4_with_positive_omega_counter_clockwise():
    w = math.radians(3.0)
    traj = ScriptedTrajectory(0.0, 0.0, 12.0, 0.0, (Segment(30.0, w),))
    x = np.array([0.0, 0.0, 12.0, 0.0])
    for k in range(1, 31):
        x = f_ctr(w, 1.0) @ x
        assert traj.state(k) == pytest.approx(x, abs=1e-9)
    # 30 s at +3 deg/s: heading +x turned to +y (counter-clockwise), speed kept.
    assert math.degrees(traj.heading(30.0)) == pytest.approx(90.0)
    assert np.hypot(*traj.state(30.0)[2:]) == pytest.approx(12.0)


def test_table2_manoeuvres():
    traj = ScriptedTrajectory(50.0, 200.0, 12.0, 0.0, SCENARIO2_SEGMENTS)
    headings = [math.degrees(traj.heading(t)) for t in (10, 20, 35, 50, 65, 80, 95)]
    assert headings == pytest.approx([0, 0, 45, 90, 45, 0, 0], abs=1e-6)
    # Continuous at the segment boundaries.
    for t in (20.0, 50.0, 80.0):
        assert traj.state(t - 1e-7) == pytest.approx(traj.state(t + 1e-7), abs=1e-4)


def test_towed_target_stays_near_its_line_and_velocity_is_the_derivative():
    traj = DraggedTrajectory((25.0, 1.0), (-0.25, 0.0), np.random.default_rng(5), deviation_std=0.3)
    ts = np.linspace(0, 80, 801)
    pos = np.array([traj.state(t)[:2] for t in ts])
    nominal = np.array([25.0, 1.0]) + np.outer(ts, [-0.25, 0.0])
    dev = pos - nominal
    assert dev.std() == pytest.approx(0.3, rel=0.5) and np.abs(dev).max() < 1.5
    h = 1e-4
    for t in (3.0, 41.0, 77.0):
        fd = (traj.state(t + h)[:2] - traj.state(t - h)[:2]) / (2 * h)
        assert traj.state(t)[2:] == pytest.approx(fd, abs=1e-5)
    # The aspect keeps changing.
    yaw = np.array([traj.heading(t) for t in ts])
    assert np.degrees(yaw.std()) > 5.0


def test_towed_path_is_fixed_by_the_generator():
    a = DraggedTrajectory((0, 0), (1, 0), np.random.default_rng(9))
    b = DraggedTrajectory((0, 0), (1, 0), np.random.default_rng(9))
    assert np.array_equal(a.state(12.3), b.state(12.3)) and a.heading(4.0) == b.heading(4.0)

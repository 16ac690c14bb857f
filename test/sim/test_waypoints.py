"""WaypointTrajectory: legs at their speeds, corners cut by arcs of the turn radius."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.sim.motion import WaypointTrajectory

POINTS = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]
SPEEDS = [1.0, 2.0, 1.5]


def _path(w: WaypointTrajectory, dt: float = 0.005) -> np.ndarray:
    return np.array([w.state(t) for t in np.arange(0.0, 2 * w.period, dt)])


def test_without_a_radius_the_legs_run_corner_to_corner():
    w = WaypointTrajectory(POINTS, SPEEDS)
    assert w.period == pytest.approx(10.0 + 5.0 + math.hypot(10, 10) / 1.5)
    assert w.state(10.0)[:2] == pytest.approx([10.0, 0.0])
    assert w.state(12.5)[2:] == pytest.approx([0.0, 2.0])


def test_arcs_keep_position_and_velocity_continuous_and_turn_at_speed_over_radius():
    w = WaypointTrajectory(POINTS, SPEEDS, turn_radius=2.0)
    s = _path(w)
    dt = 0.005
    step = np.hypot(*np.diff(s[:, :2], axis=0).T)
    speed = np.hypot(s[:, 2], s[:, 3])
    assert step.max() <= 2.0 * dt + 1e-9                      # no jump in position
    heading = np.unwrap(np.arctan2(s[:, 3], s[:, 2]))
    rate = np.abs(np.diff(heading)) / dt
    # The heading never jumps: it turns at most at speed / radius (2 m/s over 2 m: 1 rad/s).
    assert rate.max() <= 1.0 + 1e-6
    # The arc after the first corner is flown at the next leg's speed and stays 2 m from its centre.
    on_arc = (rate > 0.5) & (np.abs(speed[1:] - 2.0) < 1e-9)
    assert on_arc.any()
    # The corner point itself is never reached: the arc passes inside it.
    assert np.min(np.hypot(s[:, 0] - 10.0, s[:, 1] - 0.0)) > 0.5


def test_a_radius_too_large_for_short_legs_is_shrunk_to_half_the_shorter_leg():
    w = WaypointTrajectory([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)], 1.0, turn_radius=10.0)
    s = _path(w, 0.001)
    assert np.all(np.isfinite(s))
    # A square of 1 m legs with corners cut by 0.5 m arcs is a circle of radius 0.5 m.
    assert np.hypot(s[:, 0] - 0.5, s[:, 1] - 0.5) == pytest.approx(0.5, abs=2e-3)

"""PoseBuffer: interpolation, yaw wrap, extrapolation limit, ordering."""
from __future__ import annotations

import math

import pytest

from sonar_tracking.core.pose import ADDED, HELD, JUMPED, PoseBuffer


def test_interpolates_position_and_yaw_across_the_wrap():
    b = PoseBuffer()
    b.add(10.0, 0.0, 0.0, math.radians(170))
    b.add(12.0, 2.0, 4.0, math.radians(-170))
    x, y, yaw = b.pose_at(11.0)
    assert (x, y) == pytest.approx((1.0, 2.0))
    assert abs(math.remainder(yaw - math.pi, 2 * math.pi)) < 1e-9
    assert b.pose_at(10.0) == (0.0, 0.0, math.radians(170))


def test_nearest_pose_only_within_the_extrapolation_limit_and_out_of_order_inserts():
    b = PoseBuffer(max_extrapolation=1.0)
    b.add(5.0, 5.0, 0.0, 0.0)
    b.add(3.0, 3.0, 0.0, 0.0)
    assert b.pose_at(4.0)[0] == pytest.approx(4.0)
    assert b.pose_at(5.5)[0] == 5.0 and b.pose_at(7.0) is None and b.pose_at(1.0) is None
    b.clear()
    assert b.pose_at(4.0) is None and len(b) == 0


def stream(b, t0, t1, x0=0.0, step=0.1):
    """Poses every ``step`` s from ``t0`` to ``t1`` moving along x at 1 m/s from ``x0``; their verdicts."""
    n = int(round((t1 - t0) / step)) + 1
    return [b.add(t0 + i * step, x0 + i * step, 0.0, 0.0) for i in range(n)]


def test_a_pose_far_ahead_is_held_and_the_next_on_the_stream_discards_it():
    b = PoseBuffer()
    stream(b, 0.0, 2.0)
    assert b.add(3.15e7, 9.0, 9.0, 0.0) == HELD and b.newest == pytest.approx(2.0)
    assert stream(b, 2.1, 40.0, x0=2.1) == [ADDED] * 380   # the old stream goes on, unaffected
    assert b.held is None and b.discarded == 1
    assert b.pose_at(39.0)[0] == pytest.approx(39.0) and b.pose_at(3.15e7) is None


def test_a_jump_is_confirmed_by_its_next_neighbour_forward_and_back():
    b = PoseBuffer(max_gap=10.0, max_back=3.0)
    stream(b, 100.0, 101.0)
    assert b.add(130.0, 30.0, 0.0, 0.0) == HELD          # an outage of 29 s
    assert b.add(130.1, 30.1, 0.0, 0.0) == JUMPED
    assert b.pose_at(130.05)[0] == pytest.approx(30.05)
    assert b.add(5.0, -5.0, 0.0, 0.0) == HELD            # a new recording, 125 s back
    assert b.add(5.1, -4.9, 0.0, 0.0) == JUMPED
    assert len(b) == 2 and b.newest == pytest.approx(5.1)
    b.restart()                                           # the data's restart keeps the new recording ...
    assert b.pose_at(5.05)[0] == pytest.approx(-4.95) and len(b) == 2
    b.restart()                                           # ... and forgets poses away from its data
    assert b.pose_at(300.0) is None and len(b) == 0


def test_a_held_pose_is_confirmed_by_data_near_it_where_the_buffer_has_none():
    b = PoseBuffer(max_extrapolation=2.0)
    stream(b, 50.0, 52.0)
    assert b.add(1.0, 7.0, 3.0, 0.5) == HELD
    assert b.pose_at(51.0)[0] == pytest.approx(1.0) and b.held is not None   # the old stream still answers
    b.restart()                                                               # the data went back ...
    assert b.pose_at(1.2) == (7.0, 3.0, 0.5) and b.held is None and len(b) == 1   # ... and takes the held pose
    assert b.pose_at(9.0) is None


def test_the_first_pose_far_from_all_that_follow_is_replaced_by_them():
    b = PoseBuffer()
    b.add(3.15e7, 1.0, 1.0, 0.0)
    assert b.add(10.0, 10.0, 0.0, 0.0) == HELD and b.add(10.1, 10.1, 0.0, 0.0) == JUMPED
    assert len(b) == 2 and b.newest == pytest.approx(10.1)

"""PoseBuffer: interpolation, yaw wrap, extrapolation limit, ordering."""
from __future__ import annotations

import math

import pytest

from sonar_tracking.core.pose import PoseBuffer


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

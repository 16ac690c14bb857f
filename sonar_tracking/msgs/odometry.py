"""``nav_msgs/Odometry`` <-> planar sensor pose ``(x, y, yaw)`` and velocity.

The sonar platform's pose in the world frame (``header.frame_id``); the twist is in the child
(body) frame, as REP-105 and ``nav_msgs/Odometry`` define it.
"""
from __future__ import annotations

import math
from typing import Any

from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.stamps import header
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['odometry_to_pose', 'pose_to_odometry']


def odometry_to_pose(msg: Any) -> tuple[float, float, float]:
    """``(x, y, yaw)`` of an Odometry; AdapterError for non-finite or non-unit orientation."""
    try:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        x, y = float(p.x), float(p.y)
        qx, qy, qz, qw = float(q.x), float(q.y), float(q.z), float(q.w)
    except AttributeError as exc:
        raise AdapterError(f'not a nav_msgs/Odometry: missing field {exc.name!r}') from exc
    values = (x, y, qx, qy, qz, qw)
    if not all(map(math.isfinite, values)):
        raise AdapterError(f'odometry pose is not finite: {values}')
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if abs(norm - 1.0) > 1e-3:
        raise AdapterError(f'odometry orientation is not a unit quaternion (norm {norm:.6f})')
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return x, y, yaw


def pose_to_odometry(x: float, y: float, yaw: float, vx: float = 0.0, vy: float = 0.0, *, stamp_ns: int = 0,
                     frame_id: str = 'world', child_frame_id: str = 'sonar', types: MessageTypes | None = None) -> Any:
    """An Odometry for a planar pose with world-frame velocity ``(vx, vy)`` (stored in the body frame)."""
    types = types or rclpy_types()
    c, s = math.cos(yaw), math.sin(yaw)
    point = types.new('geometry_msgs/msg/Point', x=float(x), y=float(y), z=0.0)
    quat = types.new('geometry_msgs/msg/Quaternion', x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
    pose = types.new('geometry_msgs/msg/PoseWithCovariance',
                     pose=types.new('geometry_msgs/msg/Pose', position=point, orientation=quat))
    linear = types.new('geometry_msgs/msg/Vector3', x=c * vx + s * vy, y=-s * vx + c * vy, z=0.0)
    twist = types.new('geometry_msgs/msg/TwistWithCovariance',
                      twist=types.new('geometry_msgs/msg/Twist', linear=linear,
                                      angular=types.new('geometry_msgs/msg/Vector3', x=0.0, y=0.0, z=0.0)))
    return types.new('nav_msgs/msg/Odometry', header=header(stamp_ns, frame_id, types),
                     child_frame_id=child_frame_id, pose=pose, twist=twist)

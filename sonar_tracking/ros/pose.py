"""Where the sonar was at a stamp: odometry when there is any, else the static ``sonar_pose``.

:class:`PoseSource` subscribes ``platform/odometry`` and keeps the recent poses
(:class:`~sonar_tracking.core.pose.PoseBuffer`, interpolated at a stamp). Odometry usually arrives
just after the data it belongs to, so :meth:`PoseSource.pose_at` may say "wait": while odometry has
not yet reached the stamp and the data has waited less than ``odometry_wait`` seconds. Without any
odometry the static ``sonar_pose`` parameter ``[x, y, yaw_deg]`` is the pose.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from nav_msgs.msg import Odometry

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.pose import PoseBuffer

if TYPE_CHECKING:
    from sonar_tracking.ros.node import SonarNode

__all__ = ['PoseConfig', 'PoseSource', 'Pose', 'check_sonar_pose']

Pose = tuple[float, float, float]


def check_sonar_pose(pose: tuple[float, ...]) -> None:
    """ConfigError unless the static ``sonar_pose`` setting is ``[x, y, yaw_deg]``."""
    if len(pose) != 3:
        raise ConfigError(f'sonar_pose = {list(pose)} must be [x, y, yaw_deg]')


@dataclass(frozen=True)
class PoseConfig(Config):
    """The static pose and how long data waits for its odometry."""

    sonar_pose: tuple[float, ...] = setting((0.0, 0.0, 0.0), 'sonar [x m, y m, yaw deg] in the world frame when '
                                            'there is no platform/odometry')
    odometry_wait: float = setting(0.5, 'data waits this long for odometry at its stamp, then takes the nearest '
                                   'pose', unit='s', low=0.0, high=10.0)

    def validate(self) -> None:
        super().validate()
        check_sonar_pose(self.sonar_pose)


class PoseSource:
    """Odometry subscription + pose buffer + static fallback for one node."""

    def __init__(self, node: SonarNode, config: Callable[[], PoseConfig], qos, on_bad: Callable[[str], None],
                 on_pose: Callable[[], None] = lambda: None) -> None:
        """``on_bad(reason)`` hears a dropped odometry message, ``on_pose()`` every new pose."""
        self.node, self.config, self.on_bad, self.on_pose = node, config, on_bad, on_pose
        self.poses = PoseBuffer()
        self.newest = -math.inf
        node.subscribe(Odometry, 'platform/odometry', self._on_odometry, qos)

    @property
    def has_odometry(self) -> bool:
        return len(self.poses) > 0

    def clear(self) -> None:
        """Forget all odometry (time went back: a new recording)."""
        self.poses.clear()
        self.newest = -math.inf

    def _on_odometry(self, msg: Odometry) -> None:
        try:
            x, y, yaw = ma.odometry_to_pose(msg)
            t = ma.header_ns(msg) / 1e9
        except ma.AdapterError as exc:
            self.on_bad(f'odometry dropped: {exc}')
            return
        self.poses.add(t, x, y, yaw)
        self.newest = max(self.newest, t)
        self.on_pose()

    def pose_at(self, stamp_ns: int, waited: float = math.inf) -> Pose | None:
        """The pose at ``stamp_ns``; None to keep waiting (odometry of this stamp may be on its way)."""
        t = stamp_ns / 1e9
        cfg = self.config()
        if len(self.poses):
            if self.newest < t and waited < cfg.odometry_wait:
                return None
            pose = self.poses.pose_at(t)
            if pose is not None:
                return pose
            self.node.get_logger().warning(f'no odometry near {t:.3f} s: using sonar_pose', throttle_duration_sec=5.0)
        x, y, yaw_deg = cfg.sonar_pose
        return (x, y, math.radians(yaw_deg))

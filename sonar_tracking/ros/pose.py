"""Where the sonar was at a stamp: odometry when there is any, else the static ``sonar_pose``.

:class:`PoseSource` subscribes ``platform/odometry`` and keeps the recent poses
(:class:`~sonar_tracking.core.pose.PoseBuffer`, interpolated at a stamp). Odometry usually arrives
just after the data it belongs to, so :meth:`PoseSource.pose_at` may say "wait": while odometry has
not yet reached the stamp and the data has waited less than ``odometry_wait`` seconds. Without any
odometry the static ``sonar_pose`` parameter ``[x, y, yaw_deg]`` is the pose.

Odometry is checked before it is buffered: a position beyond :data:`~sonar_tracking.core.pose.MAX_POSITION`
is dropped, and a stamp more than ``odometry_max_gap`` seconds from the rest of the stream is held
until a neighbour confirms it (:class:`~sonar_tracking.core.pose.PoseBuffer`); each drop is counted
under ``bad_odometry`` with its reason.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from nav_msgs.msg import Odometry

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.pose import HELD, MAX_POSITION, PoseBuffer

if TYPE_CHECKING:
    from sonar_tracking.ros.node import SonarNode

__all__ = ['PoseConfig', 'PoseSource', 'Pose', 'check_sonar_pose']

Pose = tuple[float, float, float]


def check_sonar_pose(pose: tuple[float, ...]) -> None:
    """ConfigError unless the static ``sonar_pose`` setting is ``[x, y, yaw_deg]``."""
    if len(pose) != 3:
        raise ConfigError(f'sonar_pose = {list(pose)} must be [x, y, yaw_deg]')
    if not all(map(math.isfinite, pose)) or max(abs(pose[0]), abs(pose[1])) > MAX_POSITION:
        raise ConfigError(f'sonar_pose = {list(pose)} must be finite, x and y within {MAX_POSITION:.0e} m')


@dataclass(frozen=True)
class PoseConfig(Config):
    """The static pose and how long data waits for its odometry."""

    sonar_pose: tuple[float, ...] = setting((0.0, 0.0, 0.0), 'sonar [x m, y m, yaw deg] in the world frame when '
                                            'there is no platform/odometry')
    odometry_wait: float = setting(0.5, 'data waits this long for odometry at its stamp, then takes the nearest '
                                   'pose', unit='s', low=0.0, high=10.0)
    odometry_max_gap: float = setting(10.0, 'odometry stamped this far after the newest (or time_jump_reset before '
                                      'it) is held until the next message or data near it confirms the jump, and '
                                      'dropped if the stream goes on where it was', unit='s', low=0.1, high=3600.0)

    def validate(self) -> None:
        check_sonar_pose(self.sonar_pose)


class PoseSource:
    """Odometry subscription + pose buffer + static fallback for one node."""

    def __init__(self, node: SonarNode, config: Callable[[], PoseConfig], qos, on_bad: Callable[[str], None],
                 on_pose: Callable[[], None] = lambda: None) -> None:
        """``on_bad(reason)`` hears a dropped odometry message, ``on_pose()`` every new pose."""
        self.node, self.config, self.on_bad, self.on_pose = node, config, on_bad, on_pose
        self.poses = PoseBuffer()
        self.expect_odometry = False   # odometry came once: after a restart, data waits for it again
        node.subscribe(Odometry, 'platform/odometry', self._on_odometry, qos)

    @property
    def has_odometry(self) -> bool:
        return len(self.poses) > 0

    @property
    def newest(self) -> float:
        """Stamp of the newest buffered odometry [s] (-inf without any)."""
        return self.poses.newest

    def clear(self) -> None:
        """Time went back (a new recording): forget the old odometry, keeping what already belongs to
        the new recording (:meth:`~sonar_tracking.core.pose.PoseBuffer.restart`)."""
        self.poses.restart()

    def _on_odometry(self, msg: Odometry) -> None:
        try:
            x, y, yaw = ma.odometry_to_pose(msg)
            t = ma.header_ns(msg) / 1e9
        except ma.AdapterError as exc:
            self.on_bad(f'odometry dropped: {exc}')
            return
        if max(abs(x), abs(y)) > MAX_POSITION:
            self.on_bad(f'odometry at {t:.3f} s dropped: position ({x:.6g}, {y:.6g}) m is beyond '
                        f'{MAX_POSITION:.0e} m from the origin')
            return
        cfg = self.config()
        self.poses.max_gap = cfg.odometry_max_gap
        self.poses.max_back = getattr(cfg, 'time_jump_reset', self.poses.max_back)
        self.expect_odometry = True
        discarded = self.poses.discarded
        newest = self.poses.newest
        verdict = self.poses.add(t, x, y, yaw)
        if self.poses.discarded > discarded:
            self.on_bad('odometry dropped: a message stamped apart from its neighbours was not confirmed by the '
                        'next one')
        if verdict == HELD:
            self.node.say('warning', f'odometry at {t:.3f} s is {t - newest:+.3f} s from the newest ({newest:.3f} s): '
                          'held until the next message confirms the jump')
            return
        self.on_pose()

    def pose_at(self, stamp_ns: int, waited: float = math.inf) -> Pose | None:
        """The pose at ``stamp_ns``; None to keep waiting (odometry of this stamp may be on its way)."""
        t = stamp_ns / 1e9
        cfg = self.config()
        pose = self.poses.pose_at(t)   # first: data near a held odometry message confirms it
        if self.expect_odometry:
            if self.newest < t and waited < cfg.odometry_wait:
                return None
            if pose is not None:
                return pose
            self.node.get_logger().warning(f'no odometry near {t:.3f} s: using sonar_pose', throttle_duration_sec=5.0)
        x, y, yaw_deg = cfg.sonar_pose
        return (x, y, math.radians(yaw_deg))

"""Sector input of the nodes that read sonar sectors (``active_detector``, ``fls_features``).

:class:`SectorInput` subscribes ``/sonar/sector``, ``/sonar/sector_info`` and ``/platform/odometry``
and hands its node one checked sector at a time, in stamp order, with the sonar pose at that stamp:

* the image and its geometry are paired by stamp; a half that never finds its partner is dropped
  with a warning;
* a malformed pair (encoding, sizes, geometry that does not match the image) is dropped with the
  adapter's reason;
* a stamp that repeats, or goes back by at most ``time_jump_reset`` seconds, is dropped; a bigger
  step back is a new recording (a looping bag): the node's ``on_reset`` runs and input starts again;
* the pose comes from odometry interpolated at the stamp. A sector waits up to ``odometry_wait``
  seconds for odometry at or after its stamp (it usually arrives just after the sector), then
  takes the nearest pose; with no odometry at all, the ``sonar_pose`` parameter.

:class:`SectorInputConfig` declares the settings once; the nodes' configs derive from it.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, LaserScan

import msg_adapters as ma
from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.pose import PoseBuffer
from sonar_tracking.core.sector import SectorGeometry

from ._diagnostics import StageDiagnostics

__all__ = ['SectorInputConfig', 'SectorInput', 'Pose', 'check_sonar_pose']

Pose = tuple[float, float, float]


@dataclass(frozen=True)
class SectorInputConfig(Config):
    """How a node takes sectors in: static pose, odometry wait, time jumps, pairing queue."""

    sonar_pose: tuple[float, ...] = setting((0.0, 0.0, 0.0), 'sonar [x m, y m, yaw deg] in the world frame when '
                                            'there is no /platform/odometry')
    odometry_wait: float = setting(0.5, 'a sector waits this long for odometry at its stamp, then takes the '
                                   'nearest pose', unit='s', low=0.0, high=10.0)
    time_jump_reset: float = setting(3.0, 'a stamp this much older than the last one restarts the node '
                                     '(a looping bag); smaller steps back are dropped', unit='s', low=0.0, high=1e6)
    max_pending: int = setting(16, 'sector halves kept while waiting for their partner', low=1, high=1000,
                               read_only=True)

    def validate(self) -> None:
        super().validate()
        check_sonar_pose(self.sonar_pose)


def check_sonar_pose(pose: tuple[float, ...]) -> None:
    """ConfigError unless the static ``sonar_pose`` setting is ``[x, y, yaw_deg]``."""
    if len(pose) != 3:
        raise ConfigError(f'sonar_pose = {list(pose)} must be [x, y, yaw_deg]')


class SectorInput:
    """Feeds ``on_sector(stamp_ns, amplitudes, geometry, pose, frame_id) -> bool`` (False: dropped).

    ``config()`` returns the node's current :class:`SectorInputConfig`; ``use_odometry()`` says
    whether poses matter (False: every pose is the origin, for a node working in the sensor frame).
    """

    def __init__(self, node: Node, diag: StageDiagnostics, config: Callable[[], SectorInputConfig],
                 on_sector: Callable[..., bool], on_reset: Callable[[float], None],
                 use_odometry: Callable[[], bool] = lambda: True) -> None:
        self.node, self.diag, self.config = node, diag, config
        self.on_sector, self.on_reset, self.use_odometry = on_sector, on_reset, use_odometry
        self.pairer = ma.SectorPairer(config().max_pending)
        self.poses = PoseBuffer()
        self.last_stamp: int | None = None
        self._newest_odometry = -math.inf
        self._waiting: deque[tuple[int, np.ndarray, SectorGeometry, str, float]] = deque()
        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(Image, '/sonar/sector', lambda m: self._half(self.pairer.add_image, m, 'sector image'),
                                 qos)
        node.create_subscription(LaserScan, '/sonar/sector_info',
                                 lambda m: self._half(self.pairer.add_info, m, 'sector geometry'), qos)
        node.create_subscription(Odometry, '/platform/odometry', self._on_odometry, 50)
        node.create_timer(0.05, self._flush)

    @property
    def has_odometry(self) -> bool:
        return len(self.poses) > 0

    def _half(self, add, msg, what: str) -> None:
        try:
            pair = add(msg)
        except ma.AdapterError as exc:
            self.diag.report(self.node.get_logger(), 'bad_stamp', f'{what} dropped: {exc}')
            return
        for kind, stamp in self.pairer.pop_dropped():
            self.diag.report(self.node.get_logger(), 'unpaired',
                             f'sector {kind} at {stamp / 1e9:.3f} s never got its partner: dropped', level='warning')
        if pair is not None:
            self._accept(pair)

    def _on_odometry(self, msg: Odometry) -> None:
        try:
            x, y, yaw = ma.odometry_to_pose(msg)
            t = ma.header_ns(msg) / 1e9
        except ma.AdapterError as exc:
            self.diag.report(self.node.get_logger(), 'bad_odometry', f'odometry dropped: {exc}')
            return
        self.poses.add(t, x, y, yaw)
        self._newest_odometry = max(self._newest_odometry, t)
        self._flush()

    def _accept(self, pair: ma.SectorPair) -> None:
        try:
            amplitudes, geometry = ma.sector_from_messages(pair.image, pair.info)
        except ma.AdapterError as exc:
            self.diag.report(self.node.get_logger(), 'malformed', f'sector at {pair.stamp_ns / 1e9:.3f} s dropped: {exc}')
            return
        stamp = pair.stamp_ns
        newest = self._waiting[-1][0] if self._waiting else self.last_stamp
        if newest is not None and stamp <= newest:
            back = (newest - stamp) / 1e9
            if stamp == newest or back <= self.config().time_jump_reset:
                self.diag.report(self.node.get_logger(), 'stamp_order',
                                 f'sector at {stamp / 1e9:.3f} s is not newer than the last one '
                                 f'({newest / 1e9:.3f} s): dropped')
                return
            self._waiting.clear()
            self.poses.clear()
            self._newest_odometry = -math.inf
            self.last_stamp = None
            self.on_reset(back)
        self._waiting.append((stamp, amplitudes, geometry, pair.image.header.frame_id, time.monotonic()))
        self._flush()

    def _pose(self, stamp_ns: int, waited: float) -> Pose | None:
        """The sonar pose at ``stamp_ns``, or None to keep waiting for odometry."""
        if not self.use_odometry():
            return (0.0, 0.0, 0.0)
        t = stamp_ns / 1e9
        cfg = self.config()
        if len(self.poses):
            if self._newest_odometry < t and waited < cfg.odometry_wait:
                return None  # the odometry of this stamp is probably on its way
            pose = self.poses.pose_at(t)
            if pose is not None:
                return pose
            self.node.get_logger().warning(f'no odometry near {t:.3f} s: using sonar_pose', throttle_duration_sec=5.0)
        x, y, yaw_deg = cfg.sonar_pose
        return (x, y, math.radians(yaw_deg))

    def _flush(self) -> None:
        now = time.monotonic()
        while self._waiting:
            stamp, amplitudes, geometry, frame_id, received = self._waiting[0]
            pose = self._pose(stamp, now - received)
            if pose is None:
                return
            self._waiting.popleft()
            if self.on_sector(stamp, amplitudes, geometry, pose, frame_id):
                self.last_stamp = stamp

"""Sector input of the nodes that read sonar sectors (``active_detector``, ``fls_features``).

:class:`SectorInput` subscribes ``sonar/sector``, ``sonar/sector_info`` and ``platform/odometry``
and hands its node one checked sector at a time, in stamp order, with the sonar pose at that stamp:

* the image and its geometry are paired by stamp; a half that never finds its partner is dropped
  with a warning;
* a malformed pair (encoding, sizes, geometry that does not match the image or lies beyond the
  physical bounds, values that cannot be echoes) is dropped with the reason
  (:func:`~sonar_tracking.core.sector.check_sector`, the same verdict in every consumer);
* stamps follow the package's time rule (:mod:`sonar_tracking.ros.timeline`): late ones are
  dropped, a big step back restarts the node (``on_reset``);
* the pose comes from :class:`~sonar_tracking.ros.pose.PoseSource`: odometry interpolated at the
  stamp, waited for up to ``odometry_wait`` seconds, else the ``sonar_pose`` parameter.

:class:`SectorInputConfig` declares the settings once; the nodes' configs derive from it.
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from sensor_msgs.msg import Image, LaserScan

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.sector import SectorError, SectorGeometry, check_sector
from sonar_tracking.ros.node import InputConfig, SonarNode
from sonar_tracking.ros.pose import Pose, PoseConfig, PoseSource

__all__ = ['SectorInputConfig', 'SectorInput']


@dataclass(frozen=True)
class SectorInputConfig(InputConfig, PoseConfig):
    """How a node takes sectors in: QoS, time rule, static pose, odometry wait, pairing queue."""

    max_pending: int = setting(16, 'sector halves kept while waiting for their partner', low=1, high=1000,
                               read_only=True)


class SectorInput:
    """Feeds ``on_sector(stamp_ns, amplitudes, geometry, pose, frame_id) -> bool`` (False: dropped).

    ``use_odometry()`` says whether poses matter (False: every pose is the origin, for a node
    working in the sensor frame).
    """

    def __init__(self, node: SonarNode, on_sector: Callable[..., bool], on_reset: Callable[[], None],
                 use_odometry: Callable[[], bool] = lambda: True) -> None:
        self.node = node
        self.on_sector, self.on_reset, self.use_odometry = on_sector, on_reset, use_odometry
        self.pairer = ma.SectorPairer(node.config.max_pending)
        self._waiting: deque[tuple[int, np.ndarray, SectorGeometry, str, float]] = deque()
        qos = node.input_qos()
        self.pose = PoseSource(node, lambda: node.config, qos, lambda text: node.say('error', text, 'bad_odometry'),
                               self._flush)
        node.subscribe(Image, 'sonar/sector', lambda m: self._half(self.pairer.add_image, m, 'sector image'), qos)
        node.subscribe(LaserScan, 'sonar/sector_info', lambda m: self._half(self.pairer.add_info, m, 'sector geometry'),
                       qos)
        node.create_timer(0.05, node.guarded(self._flush, 'sector'))

    @property
    def has_odometry(self) -> bool:
        return self.pose.has_odometry

    def _half(self, add, msg, what: str) -> None:
        try:
            pair = add(msg)
        except ma.AdapterError as exc:
            self.node.say('error', f'{what} dropped: {exc}', 'bad_stamp')
            return
        for stamp, parts in self.pairer.pop_dropped():
            self.node.say('warning', f'sector {"/".join(parts)} at {stamp / 1e9:.3f} s never got its partner: '
                          'dropped', 'unpaired')
        if pair is not None:
            self._accept(pair)
        self._flush()

    def _accept(self, pair: ma.SectorPair) -> None:
        try:
            amplitudes, geometry = ma.sector_from_messages(pair.image, pair.info)
            check_sector(amplitudes, geometry, self.node.config.intensity.coding)
        except (ma.AdapterError, SectorError) as exc:
            self.node.say('error', f'sector at {pair.stamp_ns / 1e9:.3f} s dropped: {exc}', 'malformed')
            return
        stamp = pair.stamp_ns
        if not self.node.admit(stamp, 'sector', self._restart, self._waiting[-1][0] if self._waiting else None):
            return
        self._waiting.append((stamp, amplitudes, geometry, pair.image.header.frame_id, time.monotonic()))

    def _restart(self, last_ns: int) -> None:
        self._waiting.clear()
        self.pairer.restart(last_ns)
        self.pose.clear()
        self.on_reset()

    def _pose(self, stamp_ns: int, waited: float) -> Pose | None:
        return self.pose.pose_at(stamp_ns, waited) if self.use_odometry() else (0.0, 0.0, 0.0)

    def _flush(self) -> None:
        now = time.monotonic()
        while self._waiting:
            stamp, amplitudes, geometry, frame_id, received = self._waiting[0]
            pose = self._pose(stamp, now - received)
            if pose is None:
                return
            self._waiting.popleft()
            if self.on_sector(stamp, amplitudes, geometry, pose, frame_id):
                self.node.time.accept(stamp)

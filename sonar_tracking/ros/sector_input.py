"""Sector input of the nodes that read sonar sectors (``active_detector``, ``fls_features``).

:class:`SectorInput` subscribes ``sonar/sector``, ``sonar/sector_info`` and ``platform/odometry``
and hands its node one checked sector at a time, in stamp order, with the sonar pose at that stamp:

* the image and its geometry are paired by stamp (:mod:`sonar_tracking.msgs.pairing`); a half
  that is given up is dropped with a warning and counted, one per message, under its reason:
  ``partner_lost`` (its partner fell into a gap of the publisher's sequence numbers: the
  middleware lost it from a full queue, counted under ``queue_overflow``), ``unpaired`` (its
  partner never came otherwise), ``evicted`` (more than ``max_pending`` stamps waited;
  ``max_pending`` is at least the input queue depth by default, so a burst does not push out a
  partner still on its way) or ``duplicate``. So every message received, or lost on the way, is
  counted once: as part of a processed or dropped sector, or under one of these reasons;
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
from sonar_tracking.msgs.pairing import GIVEN_UP, UNPAIRED
from sonar_tracking.ros.node import InputConfig, SonarNode
from sonar_tracking.ros.pose import Pose, PoseConfig, PoseSource

__all__ = ['SectorInputConfig', 'SectorInput', 'PARTNER_LOST']

#: A half whose partner the middleware lost (a full queue, counted under ``queue_overflow``).
PARTNER_LOST = 'partner_lost'

_GIVEN_UP = {**GIVEN_UP, PARTNER_LOST: 'never got its partner (lost before it was read, counted under '
             'queue_overflow)'}


@dataclass(frozen=True)
class SectorInputConfig(InputConfig, PoseConfig):
    """How a node takes sectors in: QoS, time rule, static pose, odometry wait, pairing queue."""

    max_pending: int = setting(64, 'sector halves kept while waiting for their partner (at least the input queue '
                               'depth, 50, so a burst does not push out a partner still on its way)', low=1,
                               high=1000, read_only=True)


class SectorInput:
    """Feeds ``on_sector(stamp_ns, amplitudes, geometry, pose, frame_id) -> bool`` (False: dropped).

    ``use_odometry()`` says whether poses matter (False: every pose is the origin, for a node
    working in the sensor frame).
    """

    LOST_INTERVALS = 64   # recent gaps per half kept to tell a lost partner from one never sent

    def __init__(self, node: SonarNode, on_sector: Callable[..., bool], on_reset: Callable[[], None],
                 use_odometry: Callable[[], bool] = lambda: True) -> None:
        self.node = node
        self.on_sector, self.on_reset, self.use_odometry = on_sector, on_reset, use_odometry
        self.pairer = ma.SectorPairer(node.config.max_pending)
        self._waiting: deque[tuple[int, np.ndarray, SectorGeometry, str, float]] = deque()
        qos = node.input_qos()
        self.pose = PoseSource(node, lambda: node.config, qos, lambda text: node.say('error', text, 'bad_odometry'),
                               self._flush)
        # Per half: the stamp of its last message, and recent stamp intervals in which the middleware lost some.
        self._last: dict[str, int | None] = {'image': None, 'info': None}
        self._lost: dict[str, deque[tuple[int | None, int]]] = {
            part: deque(maxlen=self.LOST_INTERVALS) for part in self._last}
        node.subscribe(Image, 'sonar/sector', lambda m: self._half('image', m), qos,
                       on_lost=lambda n, m: self._lost_before('image', m))
        node.subscribe(LaserScan, 'sonar/sector_info', lambda m: self._half('info', m), qos,
                       on_lost=lambda n, m: self._lost_before('info', m))
        node.create_timer(0.05, node.guarded(self._flush, 'sector'))

    @property
    def has_odometry(self) -> bool:
        return self.pose.has_odometry

    @property
    def held(self) -> int:
        """Messages received and not yet processed or dropped: halves waiting for their partner, and
        both halves of each paired sector waiting for its pose."""
        return self.pairer.pending_parts + 2 * len(self._waiting)

    def _lost_before(self, part: str, msg) -> None:
        try:
            self._lost[part].append((self._last[part], ma.header_ns(msg)))
        except ma.AdapterError:
            pass   # the message itself is dropped for its stamp

    def _partner_lost(self, stamp: int, parts: tuple[str, ...]) -> bool:
        """Whether a partner missing at ``stamp`` fell into a gap the middleware reported."""
        return any((a is None or a < stamp) and stamp < b
                   for part in self.pairer.missing(parts) for a, b in self._lost[part])

    def _half(self, part: str, msg) -> None:
        try:
            pair = self.pairer.add_image(msg) if part == 'image' else self.pairer.add_info(msg)
            self._last[part] = ma.header_ns(msg)
        except ma.AdapterError as exc:
            self.node.say('error', f'sector {"image" if part == "image" else "geometry"} dropped: {exc}', 'bad_stamp')
            return
        for stamp, parts, reason in self.pairer.pop_dropped_with_reasons():
            if reason == UNPAIRED and self._partner_lost(stamp, parts):
                reason = PARTNER_LOST
            for given_up in parts:   # counted per message: a half is not a sector
                self.node.say('warning', f'sector {given_up} at {stamp / 1e9:.3f} s {_GIVEN_UP[reason]}: dropped',
                              reason)
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
        for stamp, *_ in self._waiting:
            self.node.say('warning', f'sector at {stamp / 1e9:.3f} s was waiting for its pose when time went back: '
                          'dropped', 'restart')
        self._waiting.clear()
        for part in self._lost:
            self._lost[part].clear()
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

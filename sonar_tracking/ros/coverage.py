"""Where the sonar looked for a scan: its coverage window from ``sonar/sector_info`` and the pose.

A tracker that knows the window ends tracks that have left it
(:class:`~sonar_tracking.core.tracking.coverage.Coverage`). Detections carry the stamp of their
sector, and the sector's geometry travels on ``sonar/sector_info`` with that stamp, so
:class:`CoverageSource` keeps the recent geometries by stamp and places the window with the
:class:`~sonar_tracking.ros.pose.PoseSource` (odometry, or the static ``sonar_pose``). Only for
sensors whose sector is the whole scan (imaging sonars, the harbour sonar): a scanning head's
sector is one slice, and a window of one slice would end the tracks in the rest of its sweep.
"""
from __future__ import annotations

from collections import OrderedDict

from sensor_msgs.msg import LaserScan

import sonar_tracking.msgs as ma
from sonar_tracking.core.tracking.coverage import Coverage
from sonar_tracking.core.tracking.errors import TrackingInputError
from sonar_tracking.ros.pose import PoseSource

__all__ = ['CoverageSource']


class CoverageSource:
    """``at(stamp_ns)``: the coverage window of the scan with that stamp, or None if its geometry
    never came (or is not a usable window)."""

    KEEP = 64

    def __init__(self, node, qos) -> None:
        self.node = node
        self.infos: OrderedDict[int, tuple[float, float, float, float]] = OrderedDict()
        node.subscribe(LaserScan, 'sonar/sector_info', self._on_info, qos)
        self.pose = PoseSource(node, lambda: node.config, qos, lambda text: node.say('error', text, 'bad_odometry'))

    def _on_info(self, msg: LaserScan) -> None:
        lo, hi = sorted((float(msg.angle_min), float(msg.angle_max)))
        self.infos[ma.header_ns(msg)] = (float(msg.range_min), float(msg.range_max), lo, hi)
        while len(self.infos) > self.KEEP:
            self.infos.popitem(last=False)

    def at(self, stamp_ns: int) -> Coverage | None:
        window = self.infos.get(stamp_ns)
        if window is None:
            return None
        pose = self.pose.pose_at(stamp_ns)   # never None without a wait limit
        if pose is None:
            return None
        x, y, yaw = pose
        try:
            return Coverage(x, y, yaw, *window)
        except TrackingInputError as exc:
            self.node.say('warning', f'sector_info at {stamp_ns / 1e9:.3f} s is no coverage window: {exc}')
            return None

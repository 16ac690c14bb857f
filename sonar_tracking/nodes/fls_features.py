"""``fls_features``: FLS image building, modified median filter, region growing, region features.

Subscribes ``/sonar/sector`` + ``/sonar/sector_info`` (paired by stamp; a half that never finds its
partner is dropped with a warning) and ``/platform/odometry`` (the sonar's pose for a moving
platform; without it the ``sonar_pose`` parameter). Publishes, whenever a sweep completes (or
every sector with ``image.publish: sector``), in this order and with one stamp (the last sector
in the image):

* ``/fls/image_info`` (``nav_msgs/MapMetaData``): the pixel <-> metres mapping of the image,
  ``map_load_time`` = the image stamp (see ``_image_info``);
* ``/fls/image`` (``sensor_msgs/Image`` ``32FC1``): the processed image the regions refer to:
  filtered, range-normalised intensity (1 = background level, 0 = no data), in OccupancyGrid
  layout (columns along x, rows along y of ``header.frame_id``);
* ``/fls/regions`` (``sensor_msgs/PointCloud2``, REGION_DTYPE): one point per region, ``x, y`` in
  the image's frame, ``range, bearing`` from the sonar, features ``f01..f30`` (Table 2); width 0
  when there are none;

and ``/diagnostics`` once a second. ``frame: world`` (default) places sectors by their pose in
``world_frame``; ``frame: sensor`` paints them in the sonar's own frame (a static sonar).

Bad input (unknown encoding, image and geometry that disagree, an empty, all-zero or non-finite
sector, a stamp older than the last) is logged and the message dropped; the node keeps running.
A stamp more than ``time_jump_reset`` seconds older than the last restarts the image (a new
recording).
"""
from __future__ import annotations

import math
import re
import time
from collections import OrderedDict, deque
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import MapMetaData, Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, LaserScan, PointCloud2

import msg_adapters as ma
from sonar_tracking.core.config import ConfigError, setting
from sonar_tracking.core.fls import FlsConfig, FlsFrame, FlsInputError, FlsProcessor
from sonar_tracking.core.pose import PoseBuffer

from ._diagnostics import StageDiagnostics
from ._image_info import grid_to_map_info
from ._params import ConfigParameters
from ._runtime import run_node

__all__ = ['FlsNodeConfig', 'FlsFeaturesNode', 'main']


@dataclass(frozen=True)
class FlsNodeConfig(FlsConfig):
    """FLS front-end settings plus the node's frames, static pose and timing."""

    frame: str = setting('world', 'frame of the image and regions: world (sectors placed by odometry or '
                         'sonar_pose) or sensor (the sonar frame, a static sonar)', choices=('world', 'sensor'),
                         read_only=True)
    world_frame: str = setting('world', 'name of the world frame (frame_id of the outputs when frame = world)',
                               read_only=True)
    sonar_pose: tuple[float, ...] = setting((0.0, 0.0, 0.0), 'sonar [x m, y m, yaw deg] in the world frame when '
                                            'there is no /platform/odometry')
    odometry_wait: float = setting(0.5, 'a sector waits this long for odometry at its stamp, then takes the '
                                   'nearest pose', unit='s', low=0.0, high=10.0)
    time_jump_reset: float = setting(3.0, 'a stamp this much older than the last one restarts the image '
                                     '(a looping bag); smaller steps back are dropped', unit='s', low=0.0, high=1e6)
    max_pending: int = setting(16, 'sector halves kept while waiting for their partner', low=1, high=1000,
                               read_only=True)

    def validate(self) -> None:
        super().validate()
        if len(self.sonar_pose) != 3:
            raise ConfigError(f'sonar_pose = {list(self.sonar_pose)} must be [x, y, yaw_deg]')


class FlsFeaturesNode(Node):
    """Runs an :class:`FlsProcessor` on paired sectors and publishes its frames."""

    #: Settings that may change while running (the rest only at start-up).
    READ_ONLY = {'frame', 'world_frame', 'max_pending', 'image.resolution'}

    def __init__(self, **kwargs) -> None:
        super().__init__('fls_features', **kwargs)
        mutable = {s.name for s in FlsNodeConfig.settings()} - self.READ_ONLY
        self.params = ConfigParameters(self, FlsNodeConfig(), on_change=self._on_change, mutable=mutable)
        self.config: FlsNodeConfig = self.params.config
        self.processor = FlsProcessor(self.config)
        self.pairer = ma.SectorPairer(self.config.max_pending)
        self.poses = PoseBuffer()
        self.last_stamp: int | None = None
        self._newest_odometry = -math.inf
        self._waiting: deque[tuple[int, np.ndarray, object, str, float]] = deque()
        self._ns_of: OrderedDict[float, int] = OrderedDict()
        self._t0_ns: int | None = None
        self.frames = 0
        self.diag = StageDiagnostics('fls_features: segmentation')
        self._last_report: dict[str, float] = {}

        sectors = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.create_subscription(Image, '/sonar/sector', self._on_image, sectors)
        self.create_subscription(LaserScan, '/sonar/sector_info', self._on_info, sectors)
        self.create_subscription(Odometry, '/platform/odometry', self._on_odometry, 50)
        out = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.pub_info = self.create_publisher(MapMetaData, '/fls/image_info', out)
        self.pub_image = self.create_publisher(Image, '/fls/image', out)
        self.pub_regions = self.create_publisher(PointCloud2, '/fls/regions', out)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_timer(1.0, self._publish_diagnostics)
        self.create_timer(0.05, self._flush_waiting)
        c = self.config
        self.get_logger().info(
            f'{c.image.resolution:g} m pixels in the {c.frame} frame, published per {c.image.publish}; filter '
            f'{c.filter.window_bins} bins x {c.filter.window_beams} beams trim {c.filter.trim}; regions from '
            f'{c.segment.seed_db:g} dB, grown to {c.segment.grow_db:g} dB, joined within {c.segment.join_distance:g} m')

    def _report(self, reason: str, text: str) -> None:
        """Count a dropped message and log why: each kind of problem at once, then at most once a
        second (a sensor sending bad data all the time must not flood the log, nor hide a new fault)."""
        self.diag.drop(reason)
        key = reason + ':' + re.sub(r'[-+0-9.e]+', '#', text)
        now = time.monotonic()
        if now - self._last_report.get(key, -math.inf) >= 1.0:
            self._last_report[key] = now
            self.get_logger().error(text)

    def _on_change(self, old: FlsNodeConfig, new: FlsNodeConfig) -> None:
        self.config = new
        self.processor.reconfigure(new)
        if new.filter != old.filter:
            self.get_logger().info('filter settings changed: the image starts again')

    # -- inputs ------------------------------------------------------------------------------
    def _on_image(self, msg: Image) -> None:
        self._handle(self.pairer.add_image, msg, 'sector image')

    def _on_info(self, msg: LaserScan) -> None:
        self._handle(self.pairer.add_info, msg, 'sector geometry')

    def _handle(self, add, msg, what: str) -> None:
        try:
            pair = add(msg)
        except ma.AdapterError as exc:
            self._report('bad_stamp', f'{what} dropped: {exc}')
            return
        for kind, stamp in self.pairer.pop_dropped():
            self.diag.drop('unpaired')
            self.get_logger().warning(f'sector {kind} at {stamp / 1e9:.3f} s never got its partner: dropped',
                                      throttle_duration_sec=1.0)
        if pair is not None:
            self._accept(pair)

    def _on_odometry(self, msg: Odometry) -> None:
        try:
            x, y, yaw = ma.odometry_to_pose(msg)
            t = ma.header_ns(msg) / 1e9
            self.poses.add(t, x, y, yaw)
            self._newest_odometry = max(self._newest_odometry, t)
        except ma.AdapterError as exc:
            self._report('bad_odometry', f'odometry dropped: {exc}')
            return
        self._flush_waiting()

    # -- processing --------------------------------------------------------------------------
    def _accept(self, pair: ma.SectorPair) -> None:
        """Check a sector pair, then queue it until its pose is known."""
        log = self.get_logger()
        try:
            amplitudes, geometry = ma.sector_from_messages(pair.image, pair.info)
        except ma.AdapterError as exc:
            self._report('malformed', f'sector at {pair.stamp_ns / 1e9:.3f} s dropped: {exc}')
            return
        stamp = pair.stamp_ns
        newest = self._waiting[-1][0] if self._waiting else self.last_stamp
        if newest is not None and stamp <= newest:
            back = (newest - stamp) / 1e9
            if stamp == newest or back <= self.config.time_jump_reset:
                self._report('stamp_order', f'sector at {stamp / 1e9:.3f} s is not newer than the last one '
                             f'({newest / 1e9:.3f} s): dropped')
                return
            log.warning(f'time went back by {back:.3f} s (a new recording?): the image starts again')
            self._waiting.clear()
            self.poses.clear()
            self._newest_odometry = -math.inf
            self.processor.reset()
            self.last_stamp = self._t0_ns = None
        self._waiting.append((stamp, amplitudes, geometry, pair.image.header.frame_id, time.monotonic()))
        self._flush_waiting()

    def _pose_for(self, stamp_ns: int, waited: float) -> tuple[float, float, float] | None:
        """The sonar pose at ``stamp_ns`` in the image frame, or None to keep waiting for odometry."""
        if self.config.frame == 'sensor':
            return (0.0, 0.0, 0.0)
        t = stamp_ns / 1e9
        if len(self.poses):
            if self._newest_odometry < t and waited < self.config.odometry_wait:
                return None  # the odometry of this stamp is probably on its way
            pose = self.poses.pose_at(t)
            if pose is not None:
                return pose
            self.get_logger().warning(f'no odometry near {t:.3f} s: using sonar_pose', throttle_duration_sec=5.0)
        x, y, yaw_deg = self.config.sonar_pose
        return (x, y, math.radians(yaw_deg))

    def _flush_waiting(self) -> None:
        now = time.monotonic()
        while self._waiting:
            stamp, amplitudes, geometry, frame_id, received = self._waiting[0]
            pose = self._pose_for(stamp, now - received)
            if pose is None:
                return
            self._waiting.popleft()
            self._process(stamp, amplitudes, geometry, frame_id, pose)

    def _process(self, stamp_ns: int, amplitudes, geometry, frame_id: str, pose) -> None:
        started = time.perf_counter()
        if self._t0_ns is None:
            self._t0_ns = stamp_ns
        t = (stamp_ns - self._t0_ns) / 1e9  # seconds since the first sector: exact enough as a float
        try:
            frames = self.processor.add_sector(amplitudes, geometry, pose, t)
        except FlsInputError as exc:
            self._report('bad_values', f'sector at {stamp_ns / 1e9:.3f} s dropped: {exc}')
            return
        self.last_stamp = stamp_ns
        self._ns_of[t] = stamp_ns
        while len(self._ns_of) > 256:
            self._ns_of.popitem(last=False)
        self._frame_id = self.config.world_frame if self.config.frame == 'world' else (frame_id or 'sonar')
        for frame in frames:
            self._publish(frame)
        self.diag.done(started)

    def _publish(self, frame: FlsFrame) -> None:
        stamp_ns = self._ns_of.get(frame.stamp, self._t0_ns + int(round(frame.stamp * 1e9)))
        self.pub_info.publish(grid_to_map_info(frame.grid, stamp_ns))
        self.pub_image.publish(ma.array_to_image(frame.image, '32FC1', stamp_ns=stamp_ns, frame_id=self._frame_id))
        self.pub_regions.publish(ma.array_to_cloud(frame.regions, stamp_ns=stamp_ns, frame_id=self._frame_id))
        self.frames += 1
        self.diag.values = {
            'frames': str(self.frames), 'regions': str(len(frame.regions)),
            'image': f'{frame.grid.width} x {frame.grid.height} px at {frame.grid.resolution:g} m',
            'sectors_in_frame': str(frame.sectors), 'background_db': f'{frame.background_db:.2f}',
            'odometry': 'yes' if len(self.poses) else 'no (sonar_pose)',
        } | {f'{k}_ms': f'{1e3 * v:.2f}' for k, v in frame.timings.items()}

    def _publish_diagnostics(self) -> None:
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking fls_features``."""
    return run_node(FlsFeaturesNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

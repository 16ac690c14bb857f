"""``gpf_tracker``: the Gaussian-particle-filter multi-target tracker of the FLS paper (§4) on FLS frames.

Subscribes the three outputs of ``fls_features`` for one frame, which share one stamp:

* ``/fls/image`` (``sensor_msgs/Image`` ``32FC1``): the processed image, 0 = no data;
* ``/fls/image_info`` (``nav_msgs/MapMetaData``, ``map_load_time`` = the image stamp): its pixel
  <-> metres mapping (``_image_info``);
* ``/fls/regions`` (``sensor_msgs/PointCloud2``, REGION_DTYPE): the segmented regions, where new
  tracks start and lost ones find their target again;

and ``/platform/odometry`` (the sonar's pose, for the line of sight of the initial spread; without
it the ``sonar_pose`` parameter). A frame is tracked once its three messages are in; halves that
never find their partners are dropped with a warning. Publishes ``/gpf/tracks`` (GPF_TRACK_DTYPE:
id, state, confirmed, the fusion used in the last update, 0 = MF, 1 = WF, covariance; width 0
when there are no tracks), ``/gpf/tracks/markers`` (RViz, namespace ``gpf``) and ``/diagnostics``.

Every setting of :class:`~sonar_tracking.core.gpf.GpfConfig` is a parameter with a descriptor
(``particles`` K, ``cues.features`` defaulting to the paper's 20, 17, 3, 6, 24, ``fusion.mode``
af|mf|wf, ``fusion.thresholds`` T_i, ``lost.max_time``...), and so are the ``features.*``
settings of ``fls_features``: give both nodes the same values (one parameter file can hold both)
so particle features are computed as the regions' are. ``config/gpf_tracker.yaml`` holds the
defaults with the paper's values marked.

Bad input never stops the node: an image of another encoding, one that does not match its
``image_info``, holding NaN, infinite or negative values, a malformed info or region cloud, or a
stamp not newer than the last is logged with its reason and the frame dropped. A stamp more than
``time_jump_reset`` older than the last restarts the tracker (a looping recording); ids are never
reused. An image without any data is no error: tracks are predicted and count the frame as a
miss, so one empty frame never ends a healthy track.
"""
from __future__ import annotations

import dataclasses
import math
import re
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import MapMetaData, Odometry
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, PointCloud2
from visualization_msgs.msg import MarkerArray

import msg_adapters as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.fls import FeatureConfig
from sonar_tracking.core.gpf import GpfConfig, GpfInputError, GpfTracker
from sonar_tracking.core.pose import PoseBuffer

from ._diagnostics import StageDiagnostics
from ._sector_input import check_sonar_pose
from ._image_info import map_info_to_grid
from ._params import ConfigParameters
from ._runtime import run_node

__all__ = ['GpfNodeConfig', 'GpfTrackerNode', 'FrameAssembler', 'check_fls_image', 'main']


@dataclass(frozen=True)
class GpfNodeConfig(GpfConfig):
    """Tracker settings, the FLS feature settings, and what the node publishes."""

    features: FeatureConfig = dataclasses.field(default_factory=FeatureConfig)
    world_frame: str = setting('world', 'frame of /gpf/tracks when /fls/image has no frame_id', read_only=True)
    seed: int = setting(0, 'seed of the particles\' random numbers: same input and seed, same tracks', low=0,
                        high=2**63 - 1, read_only=True)
    sonar_pose: tuple[float, ...] = setting((0.0, 0.0, 0.0), 'sonar [x m, y m, yaw deg] in the image frame when '
                                            'there is no /platform/odometry')
    publish_tentative: bool = setting(True, 'publish tentative tracks on /gpf/tracks too (field confirmed = 0)')
    markers_tentative: bool = setting(False, 'draw tentative tracks in /gpf/tracks/markers as well')
    marker_scale: float = setting(0.5, 'diameter of a track sphere in /gpf/tracks/markers', unit='m', low=0.0,
                                  high=1e5, low_open=True)
    time_jump_reset: float = setting(3.0, 'a stamp this much older than the last one restarts the tracker (a looping '
                                     'bag); smaller steps back are dropped', unit='s', low=0.0, high=1e6)
    max_pending: int = setting(8, 'frames kept while waiting for their image, info and regions', low=1, high=1000,
                               read_only=True)

    def validate(self) -> None:
        super().validate()
        check_sonar_pose(self.sonar_pose)


def check_fls_image(image: np.ndarray, grid_shape: tuple[int, int]) -> np.ndarray:
    """The ``/fls/image`` array as float32, or ValueError saying what is wrong with it."""
    if image.dtype != np.float32:
        raise ValueError(f'/fls/image must be 32FC1 (processed intensity), got {image.dtype}')
    if image.shape != grid_shape:
        raise ValueError(f'/fls/image is {image.shape[0]} x {image.shape[1]} pixels but its image_info says '
                         f'{grid_shape[0]} x {grid_shape[1]}')
    bad = ~np.isfinite(image)
    if bad.any():
        raise ValueError(f'/fls/image has {int(bad.sum())} NaN or infinite pixels; no-data pixels must be 0')
    if (image < 0).any():
        raise ValueError(f'/fls/image has {int((image < 0).sum())} negative pixels; intensities are >= 0')
    return image


class FrameAssembler:
    """Collects the image, info and regions of each stamp; hands out complete frames in order."""

    PARTS = ('image', 'info', 'regions')

    def __init__(self, max_pending: int = 8) -> None:
        self.max_pending = max_pending
        self._frames: OrderedDict[int, dict] = OrderedDict()
        self.dropped: list[tuple[int, tuple[str, ...]]] = []

    def add(self, part: str, stamp_ns: int, msg) -> dict | None:
        """Offer one part; returns ``{'image', 'info', 'regions'}`` once the stamp is complete."""
        frame = self._frames.setdefault(stamp_ns, {})
        frame[part] = msg
        if len(frame) == len(self.PARTS):
            del self._frames[stamp_ns]
            # Older incomplete frames will not complete now (the producer publishes in order).
            for old in [s for s in self._frames if s < stamp_ns]:
                self.dropped.append((old, tuple(sorted(self._frames.pop(old)))))
            return frame
        while len(self._frames) > self.max_pending:
            old, parts = self._frames.popitem(last=False)
            self.dropped.append((old, tuple(sorted(parts))))
        return None

    def pop_dropped(self) -> list[tuple[int, tuple[str, ...]]]:
        out, self.dropped = self.dropped, []
        return out


class GpfTrackerNode(Node):
    """Runs a :class:`~sonar_tracking.core.gpf.GpfTracker` on FLS frames."""

    READ_ONLY = {'world_frame', 'seed', 'max_pending'}

    def __init__(self, **kwargs) -> None:
        super().__init__('gpf_tracker', **kwargs)
        mutable = {s.name for s in GpfNodeConfig.settings()} - self.READ_ONLY
        self.params = ConfigParameters(self, GpfNodeConfig(), on_change=self._on_change, mutable=mutable)
        self.config: GpfNodeConfig = self.params.config
        self.tracker = GpfTracker(self.config, np.random.default_rng(self.config.seed),
                                  feature_config=self.config.features)
        self.frames = FrameAssembler(self.config.max_pending)
        self.poses = PoseBuffer()
        self.origin_ns: int | None = None
        self.last_stamp: int | None = None
        self.resets = 0
        self.processed = 0
        self.diag = StageDiagnostics('gpf_tracker: tracking')

        inputs = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
        self.create_subscription(Image, '/fls/image', lambda m: self._on_part('image', m), inputs)
        self.create_subscription(MapMetaData, '/fls/image_info', lambda m: self._on_part('info', m), inputs)
        self.create_subscription(PointCloud2, '/fls/regions', lambda m: self._on_part('regions', m), inputs)
        self.create_subscription(Odometry, '/platform/odometry', self._on_odometry, 50)
        outputs = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub_tracks = self.create_publisher(PointCloud2, '/gpf/tracks', outputs)
        self.pub_markers = self.create_publisher(MarkerArray, '/gpf/tracks/markers', outputs)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_timer(1.0, self._publish_diagnostics)
        c = self.config
        self.get_logger().info(
            f'GPF with K = {c.particles} particles, cues {list(c.cues.numbers)} in {c.cues.window:g} m windows, '
            f'fusion {c.fusion.mode} (T_i {list(c.fusion.thresholds)}), tracks end {c.lost.max_time:g} s after '
            'losing their target')

    # -- parameters -------------------------------------------------------------------------
    def _on_change(self, old: GpfNodeConfig, new: GpfNodeConfig) -> None:
        self.config = new
        self.tracker.configure(new, new.features)

    # -- inputs ------------------------------------------------------------------------------
    def _on_odometry(self, msg: Odometry) -> None:
        try:
            x, y, yaw = ma.odometry_to_pose(msg)
            self.poses.add(ma.header_ns(msg) / 1e9, x, y, yaw)
        except ma.AdapterError as exc:
            self._say('error', f'odometry dropped: {exc}', 'odometry', reason='bad_odometry')

    def _on_part(self, part: str, msg) -> None:
        try:
            stamp = ma.stamp_to_ns(msg.map_load_time) if part == 'info' else ma.header_ns(msg)
        except (ma.AdapterError, AttributeError) as exc:
            self._say('error', f'/fls/{part} message dropped: no usable stamp ({exc})', part, reason='malformed')
            return
        frame = self.frames.add(part, stamp, msg)
        for old, parts in self.frames.pop_dropped():
            self.diag.drop('unpaired')
            self._say('warning', f'frame at {old / 1e9:.3f} s had only {", ".join(parts)} (no '
                      f'{", ".join(p for p in FrameAssembler.PARTS if p not in parts)}): dropped', 'unpaired')
        if frame is not None:
            try:
                self._process(stamp, frame)
            except Exception as exc:  # noqa: BLE001 - a bug must cost one frame, not the node
                self.diag.drop('internal_error')
                self._say('error', f'frame at {stamp / 1e9:.3f} s dropped after an internal error: '
                          f'{type(exc).__name__}: {exc}', 'internal')

    def _process(self, stamp: int, frame: dict) -> None:
        started = time.perf_counter()
        where = f'frame at {stamp / 1e9:.3f} s'
        try:
            grid = map_info_to_grid(frame['info'])
            image = check_fls_image(ma.image_to_array(frame['image']), grid.shape)
            regions = ma.cloud_to_array(frame['regions'])
            names = set(regions.dtype.names or ())
            if not {'x', 'y'} <= names:
                raise ValueError(f'/fls/regions need fields x and y; the cloud has {sorted(names)}')
        except (ma.AdapterError, ValueError) as exc:
            self._say('error', f'{where} dropped: {exc}', re.sub(r'[-+0-9.e]+', '#', str(exc)), reason='malformed')
            return
        if self.last_stamp is not None and stamp <= self.last_stamp:
            back = (self.last_stamp - stamp) / 1e9
            if stamp == self.last_stamp or back <= self.config.time_jump_reset:
                self._say('warning', f'{where} is not newer than the last one ({self.last_stamp / 1e9:.3f} s): '
                          'dropped', 'order', reason='stamp_order')
                return
            self.get_logger().warning(f'time went back by {back:.3f} s (a new recording?): the tracker starts again')
            self.tracker.reset()
            self.poses.clear()
            self.origin_ns = None
            self.resets += 1
        if self.origin_ns is None:
            self.origin_ns = stamp   # times relative to the first stamp keep nanosecond resolution
        t = (stamp - self.origin_ns) * 1e-9
        pose = self._sensor_pose(stamp / 1e9)
        frame_id = frame['image'].header.frame_id or self.config.world_frame
        if not (image > 0).any():
            self._say('warning', f'{where}: the image holds no data; tracks are only predicted', 'empty')
        try:
            tracks = self.tracker.step(t, image, grid, regions, pose)
        except GpfInputError as exc:
            self._say('error', f'{where} dropped: {exc}', str(exc), reason='malformed')
            return
        rep = self.tracker.report
        if rep.bad_regions:
            self._say('warning', f'{where}: {rep.bad_regions} regions without a finite position ignored', 'regions')
        self.last_stamp = stamp
        self.processed += 1
        c = self.config
        out = tracks if c.publish_tentative else tracks[tracks['confirmed'] != 0]
        self.pub_tracks.publish(ma.array_to_cloud(out, stamp_ns=stamp, frame_id=frame_id))
        shown = tracks if c.markers_tentative else tracks[tracks['confirmed'] != 0]
        self.pub_markers.publish(ma.track_markers(shown, stamp_ns=stamp, frame_id=frame_id, ns='gpf',
                                                  scale=c.marker_scale))
        self.diag.done(started)
        self.diag.values = {
            'frames': str(self.processed), 'regions': str(rep.regions), 'tracks': str(rep.tracks),
            'confirmed': str(rep.confirmed), 'born': str(rep.born), 'ended': str(rep.ended),
            'seen': str(rep.seen), 'missed': str(rep.missed), 'refound': str(rep.reseeded),
            'fusion_mf': str(rep.mf), 'fusion_wf': str(rep.wf), 'empty_image': str(rep.empty_image),
            'resets_total': str(self.resets), 'odometry': 'yes' if len(self.poses) else 'no (sonar_pose)',
        } | {f'{k}_ms': f'{1e3 * v:.2f}' for k, v in rep.seconds.items()}

    def _sensor_pose(self, t: float) -> tuple[float, float, float]:
        if len(self.poses):
            pose = self.poses.pose_at(t)
            if pose is not None:
                return pose
        x, y, yaw_deg = self.config.sonar_pose
        return (x, y, math.radians(yaw_deg))

    def _say(self, severity: str, text: str, key: str, reason: str | None = None) -> None:
        """Count a drop under ``reason`` (if given) and log ``text``, each ``key`` at most once a second."""
        if reason is not None:
            self.diag.drop(reason)
        self.diag.log(self.get_logger(), key, text, severity)

    def _publish_diagnostics(self) -> None:
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking gpf_tracker``."""
    return run_node(GpfTrackerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

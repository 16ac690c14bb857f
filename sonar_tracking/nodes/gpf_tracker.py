"""``gpf_tracker``: the Gaussian-particle-filter multi-target tracker of the FLS paper (§4) on FLS frames.

Subscribes the three outputs of ``fls_features`` for one frame, which share one stamp:

* ``fls/image`` (``sensor_msgs/Image`` ``32FC1``): the processed image, 0 = no data;
* ``fls/image_info`` (``nav_msgs/MapMetaData``, ``map_load_time`` = the image stamp): its pixel
  <-> metres mapping (``sonar_tracking.msgs.map_info``);
* ``fls/regions`` (``sensor_msgs/PointCloud2``, REGION_DTYPE): the segmented regions, where new
  tracks start and lost ones find their target again;

and ``platform/odometry`` (the sonar's pose, for the line of sight of the initial spread; without
it the ``sonar_pose`` parameter). A frame is tracked once its three messages are in; halves that
never find their partners are dropped with a warning. Publishes ``gpf/tracks`` (GPF_TRACK_DTYPE:
id, state, confirmed, the fusion used in the last update, 0 = MF, 1 = WF, covariance; confirmed
tracks, tentative ones too with ``publish_tentative``; width 0 when there are none),
``gpf/tracks/markers`` (RViz, namespace ``gpf``), ``diagnostics`` and ``~/status`` (starting while
its kernels load, then ready: :mod:`sonar_tracking.ros.status`).

Every setting of :class:`~sonar_tracking.core.gpf.GpfConfig` is a parameter with a descriptor
(``particles`` K, ``cues.features`` defaulting to the paper's 20, 17, 3, 6, 24, ``fusion.mode``
af|mf|wf, ``fusion.thresholds`` T_i, ``lost.max_time``...), and so are the ``features.*``
settings of ``fls_features``: give both nodes the same values (one parameter file can hold both)
so particle features are computed as the regions' are. ``config/gpf_tracker.yaml`` holds the
defaults with the paper's values marked.

Bad input never stops the node: an image of another encoding, one that does not match its
``image_info``, holding NaN, infinite or negative values (beyond filter round-off, which is
clipped to 0), a malformed info or region cloud, or a late stamp is logged with its reason and the
frame dropped. A jump back in time restarts the tracker (a looping recording,
:mod:`sonar_tracking.ros.timeline`); ids are never reused. An image without any data is no error:
tracks are predicted and count the frame as a miss, so one empty frame never ends a healthy track.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
from nav_msgs.msg import MapMetaData
from sensor_msgs.msg import Image, PointCloud2

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.fls import FeatureConfig
from sonar_tracking.core.gpf import GpfConfig, GpfInputError, GpfTracker
from sonar_tracking.msgs.map_info import fls_frame
from sonar_tracking.ros import (
    InputConfig,
    PoseConfig,
    PoseSource,
    SonarNode,
    TrackOutput,
    TrackOutputConfig,
    input_profile,
    run_node,
    warmup,
)

__all__ = ['GpfNodeConfig', 'GpfTrackerNode', 'main']

@dataclass(frozen=True)
class GpfNodeConfig(GpfConfig, InputConfig, PoseConfig, TrackOutputConfig):
    """Tracker settings, the FLS feature settings, input QoS, time rule, pose, and what the node publishes."""

    features: FeatureConfig = dataclasses.field(default_factory=FeatureConfig)
    world_frame: str = setting('world', 'frame of gpf/tracks when fls/image has no frame_id', read_only=True)
    seed: int = setting(0, 'seed of the particles\' random numbers: same input and seed, same tracks', low=0,
                        high=2**63 - 1, read_only=True)
    marker_scale: float = setting(0.5, 'diameter of a track sphere in gpf/tracks/markers', unit='m', low=0.0,
                                  high=1e5, low_open=True)
    max_pending: int = setting(32, 'frames kept while waiting for their image, info and regions (a burst of '
                               'frames whose images lag)', low=1, high=1000, read_only=True)


class GpfTrackerNode(SonarNode):
    """Runs a :class:`~sonar_tracking.core.gpf.GpfTracker` on FLS frames."""

    PARTS = ('image', 'info', 'regions')

    def __init__(self, **kwargs) -> None:
        super().__init__('gpf_tracker', GpfNodeConfig(), 'gpf_tracker: tracking', **kwargs)
        self.tracker = GpfTracker(self.config, np.random.default_rng(self.config.seed),
                                  feature_config=self.config.features)
        # A throwaway tracker of the same settings: the node's generator stays untouched.
        self.warm_up(warmup.gpf, lambda: GpfTracker(self.config, np.random.default_rng(0),
                                                    feature_config=self.config.features))
        self.frames = ma.StampPairer(self.PARTS, self.config.max_pending)
        self.origin_ns: int | None = None
        self.resets = self.processed = 0
        # fls_features' outputs: between the package's nodes always reliable (input_qos is for the
        # vehicle's odometry); a burst of frames (a replay) waits instead of being overwritten.
        inputs = input_profile('reliable', 50)
        self.subscribe(Image, 'fls/image', lambda m: self._on_part('image', m), inputs)
        self.subscribe(MapMetaData, 'fls/image_info', lambda m: self._on_part('info', m), inputs)
        self.subscribe(PointCloud2, 'fls/regions', lambda m: self._on_part('regions', m), inputs)
        self.pose = PoseSource(self, lambda: self.config, self.input_qos(50),
                               lambda text: self.say('error', text, 'bad_odometry'))
        self.out = TrackOutput(self, 'gpf/tracks', 'gpf')
        self.get_logger().info(self.config.describe())

    def on_change(self, old: GpfNodeConfig, new: GpfNodeConfig) -> None:
        self.tracker.configure(new, new.features)

    def _restart(self, last_ns: int) -> None:
        self.frames.restart(last_ns)
        self.tracker.reset()
        self.pose.clear()
        self.origin_ns = None
        self.resets += 1
        self.diag.values['resets_total'] = str(self.resets)   # SonarNode reports the restart at once

    # -- inputs ------------------------------------------------------------------------------
    def _on_part(self, part: str, msg) -> None:
        try:
            stamp = ma.stamp_to_ns(msg.map_load_time) if part == 'info' else ma.header_ns(msg)
        except (ma.AdapterError, AttributeError) as exc:
            self.say('error', f'fls/{part} message dropped: no usable stamp ({exc})', 'malformed')
            return
        frame = self.frames.add(part, stamp, msg)
        for old, parts, reason in self.frames.pop_dropped_with_reasons():
            for given_up in parts:   # counted per message: a part is not a frame
                self.say('warning', f'fls/{given_up} of the frame at {old / 1e9:.3f} s {ma.GIVEN_UP[reason]} (no '
                         f'{", ".join(self.frames.missing(parts))}): dropped', reason)
        if frame is not None:
            self._process(stamp, frame)

    def _process(self, stamp: int, frame: dict) -> None:
        started = time.perf_counter()
        where = f'frame at {stamp / 1e9:.3f} s'
        try:
            grid, image, regions = fls_frame(frame['image'], frame['info'], frame['regions'])
        except (ma.AdapterError, ValueError) as exc:
            self.say('error', f'{where} dropped: {exc}', 'malformed')
            return
        if not self.admit(stamp, 'frame', self._restart):
            return
        if self.origin_ns is None:
            self.origin_ns = stamp   # times relative to the first stamp keep nanosecond resolution
        t = (stamp - self.origin_ns) * 1e-9
        pose = self.pose.pose_at(stamp)
        if not (image > 0).any():
            self.say('warning', f'{where}: the image holds no data; tracks are only predicted')
        try:
            tracks = self.tracker.step(t, image, grid, regions, pose)
        except GpfInputError as exc:
            self.say('error', f'{where} dropped: {exc}', 'malformed')
            return
        rep = self.tracker.report
        for text in rep.warnings():
            self.say('warning', f'{where}: {text}')
        self.time.accept(stamp)
        self.processed += 1
        self.out.publish(tracks, stamp, frame['image'].header.frame_id or self.config.world_frame, self.config)
        self.diag.done(started)
        self.diag.values = {'frames': str(self.processed), 'resets_total': str(self.resets),
                            'odometry': 'yes' if self.pose.has_odometry else 'no (sonar_pose)'} | rep.summary()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking gpf_tracker``."""
    return run_node(GpfTrackerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

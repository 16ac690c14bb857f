"""``imm_ipda_tracker``: the IMM-IPDA multi-target tracker of the ESC paper (§2.4) on ``detections``.

Subscribes ``detections`` (``DETECTION_DTYPE`` clouds in the world frame: positions, the
converted-measurement covariance ``cov_xx, cov_xy, cov_yy`` and the SCMDE ``clutter_density``),
``platform/odometry`` (the sonar pose: tracking is in the world frame, so the platform's motion is
already in the detections; it places the coverage window and shows in the diagnostics) and, with
``coverage: scan``, ``sonar/sector_info`` (the window each scan covered: a track that stays outside
it for ``track.outside_time`` ends). Publishes ``tracks`` (``TRACK_DTYPE``: confirmed
tracks, and tentative ones too with ``publish_tentative``; width 0 when there are none),
``tracks/markers``, ``diagnostics`` and ``~/status`` (starting while its kernels load, then
ready: :mod:`sonar_tracking.ros.status`).

Every model setting and threshold is a parameter with a descriptor
(``ros2 param describe /imm_ipda_tracker NAME``); changes apply to the running tracker, and a
change of the mode set (``imm.models``) restarts it. ``config/imm_ipda.yaml`` holds the paper's
values.

Bad input never stops the node:

* a malformed cloud (unknown field types, short data, missing ``x``/``y``) is dropped with the
  adapter's reason;
* detection rows with NaN, a covariance that is not positive definite or a clutter density that
  is not positive are dropped one by one, with their reasons in the log;
* stamps follow the package's time rule (:mod:`sonar_tracking.ros.timeline`): a late or repeated
  stamp drops the message, a jump back restarts the tracker cleanly (all tracks end, new ones get
  new ids).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from sensor_msgs.msg import PointCloud2

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig, TrackingError
from sonar_tracking.core.tracking.detections import detections_to_measurements
from sonar_tracking.ros import (
    CoverageSource,
    InputConfig,
    PoseConfig,
    SonarNode,
    TrackOutput,
    TrackOutputConfig,
    input_profile,
    run_node,
    warmup,
)

__all__ = ['TrackerNodeConfig', 'ImmIpdaTrackerNode', 'main']

@dataclass(frozen=True)
class TrackerNodeConfig(TrackerConfig, InputConfig, PoseConfig, TrackOutputConfig):
    """Tracker settings, input QoS and time rule, the sonar pose, and what the node publishes."""

    world_frame: str = setting('world', 'frame of detections and tracks', read_only=True)
    coverage: str = setting('none', "'scan': end tracks that leave the window of sonar/sector_info (a sensor whose "
                            "sector is the whole scan: imaging sonars, the harbour sonar); 'none': no window",
                            choices=('none', 'scan'), read_only=True)
    marker_scale: float = setting(10.0, 'diameter of a track sphere in tracks/markers', unit='m',
                                  low=0.0, high=1e5, low_open=True)


class ImmIpdaTrackerNode(SonarNode):
    """Runs an :class:`ImmIpdaTracker` on ``detections``."""

    def __init__(self, **kwargs) -> None:
        super().__init__('imm_ipda_tracker', TrackerNodeConfig(), 'imm_ipda_tracker: tracking', **kwargs)
        self.tracker = ImmIpdaTracker(self.config)
        self.warm_up(warmup.tracker, self.config)
        self.origin_ns: int | None = None
        self.rejected_rows = 0
        self.resets = 0
        self._warned: set[str] = set()
        # The detector's output: between the package's nodes always reliable (input_qos: sensor topics).
        self.subscribe(PointCloud2, 'detections', self._process, input_profile('reliable', 100))
        self.coverage = CoverageSource(self, self.input_qos(100))
        self.out = TrackOutput(self, 'tracks', 'tracks')
        modes = ', '.join(m.name for m in self.tracker.modes)
        self.get_logger().info(f'IMM-IPDA with modes {modes}; P_D {self.config.detection.probability:g}, '
                               f'P_G {self.config.detection.gate_probability:g}, clutter density from '
                               f'{self.config.clutter.source}; tracks in frame {self.config.world_frame!r}')

    def on_change(self, old: TrackerNodeConfig, new: TrackerNodeConfig) -> None:
        if self.tracker.configure(new):
            self.get_logger().info(f'modes changed to {new.imm.models}: tracker restarted')

    def _restart(self, last_ns: int) -> None:
        self.tracker.reset()
        self.origin_ns = None
        self.resets += 1

    # -- inputs ------------------------------------------------------------------------------
    def _process(self, msg: PointCloud2) -> None:
        started = time.perf_counter()
        try:
            stamp = ma.header_ns(msg)
            records = ma.cloud_to_array(msg)
            z, R, rho, note = detections_to_measurements(records)
        except (ma.AdapterError, ValueError) as exc:
            self.say('error', f'detections message dropped: {exc}', 'malformed')
            return
        if note:
            self._warn_once(note)
        frame = msg.header.frame_id
        if frame and frame != self.config.world_frame:
            self._warn_once(f'detections are in frame {frame!r}, tracks are published in '
                            f'{self.config.world_frame!r}: set world_frame if that is wrong')
        if not self.admit(stamp, 'detections', self._restart):
            return
        if self.origin_ns is None:
            self.origin_ns = stamp          # times relative to the first stamp keep nanosecond resolution
        try:
            window = self.coverage.at(stamp) if self.config.coverage == 'scan' else None
            tracks = self.tracker.step((stamp - self.origin_ns) * 1e-9, z, R, rho, coverage=window)
        except TrackingError as exc:           # shapes are ours, so this is a bug worth seeing
            self.say('error', f'detections at {stamp / 1e9:.6f} s dropped: {exc}', 'tracker_error')
            return
        self.time.accept(stamp)
        rep = self.tracker.report
        if rep.rejected:
            self.rejected_rows += len(rep.rejected)
            shown = '; '.join(str(r) for r in rep.rejected[:3])
            more = f' (and {len(rep.rejected) - 3} more)' if len(rep.rejected) > 3 else ''
            self.say('warning', f'detections at {stamp / 1e9:.6f} s: dropped {len(rep.rejected)} of '
                     f'{rep.n_measurements} detections: {shown}{more}')
        self.out.publish(tracks, stamp, self.config.world_frame, self.config)
        self.diag.done(started)
        self.diag.values = self._values(len(z))

    def _values(self, n_detections: int) -> dict[str, str]:
        return {'detections': str(n_detections), **self.tracker.report.summary(),
                'rejected_rows_total': str(self.rejected_rows), 'resets_total': str(self.resets)}

    def status_values(self) -> dict[str, str]:
        pose = self.coverage.pose
        if not pose.has_odometry:
            return {}
        x, y, yaw = pose.pose_at(int(pose.newest * 1e9))
        return {'platform_pose': f'x {x:.2f} m, y {y:.2f} m, yaw {np.degrees(yaw):.1f} deg at {pose.newest:.3f} s'}

    def _warn_once(self, text: str) -> None:
        if text not in self._warned:
            self._warned.add(text)
            self.get_logger().warning(text)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking imm_ipda_tracker``."""
    return run_node(ImmIpdaTrackerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

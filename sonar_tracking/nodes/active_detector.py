"""``active_detector``: threshold, SCMDE and extremum-seeking threshold control (ESC paper Fig. 2).

Subscribes ``sonar/sector`` + ``sonar/sector_info`` (paired by stamp), ``platform/odometry``
(sensor pose; without it the ``sonar_pose`` parameter) and ``tracks`` (for
``esc.density_source: best_track``, and the confirmed tracks whose detections ESC leaves out with
``esc.exclude_radius``). Publishes ``detections``, ``detector/threshold`` (the
threshold applied to the scan just processed; depth 1, transient local, so a late reader gets the
current value; with a CFAR ``threshold.method`` it is the CFAR scale alpha, dimensionless: a cell is
a detection where its intensity exceeds alpha times the level of its training cells),
``detector/clutter_density`` (the density ESC saw) and ``diagnostics`` (with the
threshold and the stamp of the scan it was applied to). Services ``~/esc/enable`` (SetBool; sets
the ``esc.enabled`` parameter, so both always agree) and ``~/esc/reset`` (Trigger; the response
message is the state as JSON: threshold, clutter density, scan count after the reset, and under
``reset_from`` the state that was reset). Its state is on ``~/status`` (starting, learning while
the structure background holds detections back, ready: :mod:`sonar_tracking.ros.status`).

Sector input (pairing, bad messages, the time rule, the pose from odometry) is
:class:`~sonar_tracking.ros.sector_input.SectorInput`; a jump back in time restarts the detector
from ``threshold.initial`` (CFAR: from the scale of ``cfar.pfa``).
"""
from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass

import numpy as np
from rclpy.parameter import Parameter
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.detection import (
    ActiveDetector,
    DetectionInputError,
    DetectorConfig,
    best_track_focus,
    resolve_desired_density,
    tracked_positions,
)
from sonar_tracking.resources import config_path
from sonar_tracking.ros import (
    SectorInput,
    SectorInputConfig,
    SonarNode,
    latest_profile,
    output_profile,
    run_node,
    warmup,
    warmup_left,
)

__all__ = ['DetectorNodeConfig', 'ActiveDetectorNode', 'main', 'desired_density']


@dataclass(frozen=True)
class DetectorNodeConfig(DetectorConfig, SectorInputConfig):
    """Detector settings, sector input settings (QoS, static pose, time jumps) and the output frame."""

    world_frame: str = setting('world', 'frame of detections', read_only=True)


def detector_config(config: DetectorNodeConfig, enabled: bool | None = None) -> DetectorConfig:
    """The detector's own settings out of the node's (``esc.enabled`` replaced when given)."""
    core = DetectorConfig(**{f.name: getattr(config, f.name) for f in dataclasses.fields(DetectorConfig)})
    return core if enabled is None else dataclasses.replace(core, esc=dataclasses.replace(core.esc, enabled=enabled))


def desired_density(config: DetectorConfig) -> float:
    """rho_D: the parameter, or the package's desired-density table at ``esc.snr_db`` when it is 0."""
    return resolve_desired_density(config, lambda: config_path('desired_density.yaml'))


class ActiveDetectorNode(SonarNode):
    """Runs an :class:`ActiveDetector` on paired sectors."""

    def __init__(self, **kwargs) -> None:
        super().__init__('active_detector', DetectorNodeConfig(), 'active_detector: detection',
                         check=desired_density, **kwargs)
        self.detector = ActiveDetector(detector_config(self.config), desired_density(self.config))
        self.warm_up(warmup.detector, self.detector.config, self.detector.desired_density)
        self.watch_warmup(lambda: warmup_left(self.detector.warmup, self.detector.config.structure,
                                              None if self.time.last_ns is None else self.time.last_ns / 1e9))
        self.best_track: tuple[float, float] | None = None
        self.tracked: np.ndarray | None = None      # confirmed tracks' positions (esc.exclude_radius)
        self.input = SectorInput(self, self._process, self._on_reset)
        self.subscribe(PointCloud2, 'tracks', self._on_tracks, 10)
        self.pub_det = self.create_publisher(PointCloud2, 'detections', output_profile())
        self.pub_threshold = self.create_publisher(Float64, 'detector/threshold', latest_profile())
        self.pub_density = self.create_publisher(Float64, 'detector/clutter_density', output_profile())
        self.create_service(SetBool, '~/esc/enable', self._srv_enable)
        self.create_service(Trigger, '~/esc/reset', self._srv_reset)
        self.pub_threshold.publish(Float64(data=self.detector.threshold))
        esc = 'on' if self.detector.enabled else 'off'
        cfar = self.detector.cfar
        test = '' if cfar is None else (f'{cfar.method.upper()}-CFAR (P_fa {cfar.config.pfa:g} per cell, '
                                        f'{cfar.training_cells} training cells), scale ')
        self.get_logger().info(f'{test}threshold {self.detector.threshold:g}, ESC {esc}, '
                               f'desired clutter density {self.detector.desired_density:.3g} /m^2')

    def on_change(self, old: DetectorNodeConfig, new: DetectorNodeConfig) -> None:
        core = detector_config(new, enabled=self.detector.config.esc.enabled)
        if core != self.detector.config:            # more than the ESC on/off switch
            try:
                self.detector.reconfigure(core)     # intensity, structure, max_detections: ESC goes on
            except ValueError:
                self.detector = ActiveDetector(core, desired_density(core))
                self.pub_threshold.publish(Float64(data=self.detector.threshold))
                self.get_logger().info(f'detector parameters changed: restarted from threshold '
                                       f'{self.detector.threshold:g}')
        self.detector.enabled = new.esc.enabled
        self._state_values()   # SonarNode reports the change at once

    # -- inputs ------------------------------------------------------------------------------
    def _on_tracks(self, msg: PointCloud2) -> None:
        try:
            tracks = ma.cloud_to_array(msg)
        except ma.AdapterError as exc:
            self.say('error', f'tracks message unusable: {exc}', 'bad_tracks')
            return
        if not {'x', 'y', 'existence', 'confirmed'} <= set(tracks.dtype.names or ()):
            self.say('error', f'tracks message without x, y, existence, confirmed: {tracks.dtype.names}', 'bad_tracks')
            return
        self.best_track = best_track_focus(tracks)
        self.tracked = tracked_positions(tracks, self.detector.config.esc.exclude_existence)

    # -- processing --------------------------------------------------------------------------
    def _on_reset(self) -> None:
        self.detector.reset()
        self.best_track = None
        self.tracked = None

    def _process(self, stamp: int, amplitudes: np.ndarray, geometry, pose, frame_id: str) -> bool:
        started = time.perf_counter()
        focus = self.best_track if self.config.esc.density_source == 'best_track' else None
        try:
            result = self.detector.process(amplitudes, geometry, pose, focus, stamp=stamp / 1e9,
                                           tracked_xy=self.tracked)
        except DetectionInputError as exc:
            self.say('error', f'sector at {stamp / 1e9:.3f} s dropped: {exc}', 'bad_values')
            return False
        self.pub_det.publish(ma.array_to_cloud(result.detections, stamp_ns=stamp, frame_id=self.config.world_frame))
        self.pub_threshold.publish(Float64(data=result.threshold))
        self.pub_density.publish(Float64(data=result.mean_density))
        self.diag.done(started)
        self.diag.values = result.summary() | {
            'threshold_stamp': f'{stamp / 1e9:.6f}', 'desired_clutter_density': f'{self.detector.desired_density:.4g}',
            'esc': 'on' if self.detector.enabled else 'off',
            'odometry': 'yes' if self.input.has_odometry else 'no (sonar_pose)'}
        return True

    # -- services ----------------------------------------------------------------------------
    def _srv_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        result = self.set_parameters([Parameter('esc.enabled', value=bool(request.data))])[0]
        response.success = result.successful
        response.message = (f'ESC {"on" if request.data else "off: threshold frozen"}; next threshold '
                            f'{self.detector.threshold:g}' if result.successful else result.reason)
        return response

    def _srv_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        before = self.detector.state()
        self.detector.reset()
        self.pub_threshold.publish(Float64(data=self.detector.threshold))
        self._state_values()
        self.report_now()
        response.success = True
        response.message = json.dumps(self.detector.state() | {'reset_from': before})
        return response

    def _state_values(self) -> None:
        """The detector's state in the diagnostics values (after a reset or a switch, before the next sector)."""
        self.diag.values.update({'next_threshold': f'{self.detector.threshold:.4f}',
                                 'esc': 'on' if self.detector.enabled else 'off'})


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking active_detector``."""
    return run_node(ActiveDetectorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

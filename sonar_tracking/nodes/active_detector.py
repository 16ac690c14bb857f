"""``active_detector``: threshold, SCMDE and extremum-seeking threshold control (ESC paper Fig. 2).

Subscribes ``/sonar/sector`` + ``/sonar/sector_info`` (paired by stamp), ``/platform/odometry``
(sensor pose; without it the ``sonar_pose`` parameter) and ``/tracks`` (for
``esc.density_source: best_track``). Publishes ``/detections``, ``/detector/threshold`` (the
threshold applied to the scan just processed, transient local), ``/detector/clutter_density``
(the density ESC saw) and ``/diagnostics``. Services ``~/esc/enable`` (SetBool) and
``~/esc/reset`` (Trigger; the response message is the state as JSON: threshold, clutter density,
scan count after the reset, and under ``reset_from`` the state that was reset).

Sector input (pairing, bad messages, time order, the pose from odometry) is
:class:`~sonar_tracking.nodes._sector_input.SectorInput`: a repeated stamp or one slightly older
than the last sector is an error and the sector is dropped with the detector state untouched; a
jump back by more than ``time_jump_reset`` seconds means a new recording (a looping bag): the
detector restarts from ``threshold.initial``.
"""
from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

import msg_adapters as ma
from sonar_tracking.core.config import ConfigError, setting
from sonar_tracking.core.detection import (ActiveDetector, DesiredDensityTable, DetectionInputError, DetectorConfig,
                                           TableError)
from sonar_tracking.resources import config_path

from ._diagnostics import StageDiagnostics
from ._params import ConfigParameters
from ._runtime import run_node
from ._sector_input import SectorInput, SectorInputConfig

__all__ = ['DetectorNodeConfig', 'ActiveDetectorNode', 'main', 'resolve_desired_density']


@dataclass(frozen=True)
class DetectorNodeConfig(DetectorConfig, SectorInputConfig):
    """Detector settings, sector input settings (static pose, time jumps) and the output frame."""

    world_frame: str = setting('world', 'frame of /detections', read_only=True)


def resolve_desired_density(config: DetectorConfig) -> float:
    """rho_D: the parameter, or the desired-density table at ``esc.snr_db`` when it is 0."""
    if config.esc.desired_clutter_density > 0:
        return config.esc.desired_clutter_density
    try:
        table = DesiredDensityTable.load(config_path('desired_density.yaml'))
        return table.lookup(config.esc.snr_db)
    except (FileNotFoundError, TableError) as exc:
        raise ConfigError(f'esc.desired_clutter_density = 0 asks for the desired-density table, but: {exc}') from None


class ActiveDetectorNode(Node):
    """Runs an :class:`ActiveDetector` on paired sectors."""

    def __init__(self, **kwargs) -> None:
        super().__init__('active_detector', **kwargs)
        self.params = ConfigParameters(self, DetectorNodeConfig(), on_change=self._on_change,
                                       check=resolve_desired_density)
        self.config: DetectorNodeConfig = self.params.config
        self.detector = self._make_detector(self.config)
        self.best_track: tuple[float, float] | None = None
        self.diag = StageDiagnostics('active_detector: detection')
        self.input = SectorInput(self, self.diag, lambda: self.config, self._process, self._on_reset)
        self.create_subscription(PointCloud2, '/tracks', self._on_tracks, 10)
        # Deep writer queues: a recorder or tracker that falls behind for a moment under load still
        # gets every scan (a reliable writer drops what falls out of its queue).
        self.pub_det = self.create_publisher(PointCloud2, '/detections', QoSProfile(depth=100))
        latched = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_threshold = self.create_publisher(Float64, '/detector/threshold', latched)
        self.pub_density = self.create_publisher(Float64, '/detector/clutter_density', 100)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_service(SetBool, '~/esc/enable', self._srv_enable)
        self.create_service(Trigger, '~/esc/reset', self._srv_reset)
        self.create_timer(1.0, self._publish_diagnostics)
        self.pub_threshold.publish(Float64(data=self.detector.threshold))
        self.get_logger().info(f'threshold {self.detector.threshold:g}, ESC {"on" if self.detector.enabled else "off"}, '
                               f'desired clutter density {self.detector.desired_density:.3g} /m^2')

    def _make_detector(self, config: DetectorNodeConfig) -> ActiveDetector:
        return ActiveDetector(config, resolve_desired_density(config))

    def _on_change(self, old: DetectorNodeConfig, new: DetectorNodeConfig) -> None:
        self.config = new

        def algorithm(c: DetectorNodeConfig) -> tuple:
            return c.threshold, c.cells, c.scmde, dataclasses.replace(c.esc, enabled=True)

        if algorithm(old) != algorithm(new):
            enabled = self.detector.enabled if old.esc.enabled == new.esc.enabled else new.esc.enabled
            self.detector = self._make_detector(new)
            self.detector.enabled = enabled
            self.pub_threshold.publish(Float64(data=self.detector.threshold))
            self.get_logger().info(f'detector parameters changed: restarted from threshold {self.detector.threshold:g}')
        elif old.esc.enabled != new.esc.enabled:
            self.detector.enabled = new.esc.enabled

    # -- inputs ------------------------------------------------------------------------------
    def _on_tracks(self, msg: PointCloud2) -> None:
        try:
            tracks = ma.cloud_to_array(msg)
            confirmed = tracks[tracks['confirmed'] > 0] if len(tracks) else tracks
            ok = confirmed[np.isfinite(confirmed['x']) & np.isfinite(confirmed['y'])] if len(confirmed) else confirmed
            if len(ok):
                best = ok[np.argmax(ok['existence'])]
                self.best_track = (float(best['x']), float(best['y']))
            else:
                self.best_track = None
        except (ma.AdapterError, ValueError) as exc:
            self.get_logger().error(f'/tracks message unusable: {exc}', throttle_duration_sec=1.0)

    # -- processing --------------------------------------------------------------------------
    def _on_reset(self, back: float) -> None:
        self.get_logger().warning(f'time went back by {back:.3f} s (a new recording?): detector restarted from '
                                  f'threshold {self.config.threshold.initial:g}')
        self.detector.reset()
        self.best_track = None

    def _process(self, stamp: int, amplitudes: np.ndarray, geometry, pose, frame_id: str) -> bool:
        started = time.perf_counter()
        focus = self.best_track if self.config.esc.density_source == 'best_track' else None
        try:
            result = self.detector.process(amplitudes, geometry, pose, focus)
        except DetectionInputError as exc:
            self.diag.report(self.get_logger(), 'bad_values', f'sector at {stamp / 1e9:.3f} s dropped: {exc}')
            return False
        self.pub_det.publish(ma.array_to_cloud(result.detections, stamp_ns=stamp, frame_id=self.config.world_frame))
        self.pub_threshold.publish(Float64(data=result.threshold))
        self.pub_density.publish(Float64(data=result.mean_density))
        self.diag.done(started)
        self.diag.values = {'threshold': f'{result.threshold:.4f}', 'next_threshold': f'{result.next_threshold:.4f}',
                            'clutter_density': f'{result.mean_density:.4g}',
                            'desired_clutter_density': f'{self.detector.desired_density:.4g}',
                            'detections': str(len(result.detections)), 'esc': 'on' if self.detector.enabled else 'off',
                            'odometry': 'yes' if self.input.has_odometry else 'no (sonar_pose)'}
        return True

    # -- services and diagnostics ------------------------------------------------------------
    def _srv_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        self.detector.enabled = bool(request.data)
        response.success = True
        response.message = (f'ESC {"on" if request.data else "off: threshold frozen"}; '
                             f'next threshold {self.detector.threshold:g}')
        return response

    def _srv_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        before = self.detector.state()
        self.detector.reset()
        self.pub_threshold.publish(Float64(data=self.detector.threshold))
        response.success = True
        response.message = json.dumps(self.detector.state() | {'reset_from': before})
        return response

    def _publish_diagnostics(self) -> None:
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking active_detector``."""
    return run_node(ActiveDetectorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

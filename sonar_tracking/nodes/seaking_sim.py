"""``seaking_sim``: the simulated sonar: a scanning SeaKing (675/325 kHz), the harbour sonar, or a
multibeam imaging sonar (Oculus, Gemini, ARIS classes; one frame per sector).

Publishes, per sector (DESIGN §4): ``sonar/sector`` (32FC1 amplitudes; mono8 dB counts with
``output.coding: db``, as the ``*_structured`` scenarios do), ``sonar/sector_info`` (its geometry,
same header), ``sonar/fan`` (mono8 picture, painted only while someone listens), ``sonar/truth`` and
``platform/odometry``; with ``publish_projected`` also ``sonar_image``, the sector as the
``marine_acoustic_msgs/ProjectedSonarImage`` an imaging-sonar driver publishes (where that package
is built; otherwise an error at start and a WARN in diagnostics); and ``diagnostics`` once a second
and at every change of state (start, end, clock): the rate of sectors (``rate_hz``, decaying if the
simulator stalls), scenario, preset, stamps, simulated time, the clock's state and the subscribers
of every output. ``rate`` sets the pace (0: as fast as the reliable readers acknowledge; falling
behind never skips a sector) and ``stamps`` the clock the messages carry
(:class:`~sonar_tracking.ros.pacing.Pacer`): ``wall``, ``sim`` (from ``stamp_offset``; the same seed
gives the same messages bit for bit), or ``auto`` (``wall`` when starting at ``rate`` 1).

Clock model (:mod:`sonar_tracking.ros.pacing`): the processing nodes work on message stamps, so
the simulator publishes no ``/clock`` unless asked to (``publish_clock``), whatever its stamps.
Asked, it publishes the stamps' clock at the simulated time now, in steps of at most
``clock_period`` (10 ms) of simulated time, reaching each sector's stamp before the sector is
published and never going back; and only if no other node of the domain publishes ``/clock``: it
refuses (one error naming the other node, a WARN in its diagnostics) when one does, and of two
started together the one whose publisher GID sorts lowest keeps it. The first sector waits until
the clock has been claimed or refused (about a second).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Image, LaserScan, PointCloud2

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.fan import PolarCanvas, to_mono8
from sonar_tracking.msgs.odometry import pose_to_odometry
from sonar_tracking.ros import (
    ConfigParameters,
    Pacer,
    PacingConfig,
    StageDiagnostics,
    SubscriberGate,
    declare_choice,
    output_profile,
    run_node,
)
from sonar_tracking.ros.pacing import SimClock
from sonar_tracking.sim import SimConfig, SimSector, Simulator, describe
from sonar_tracking.sim.presets import SCENARIOS

__all__ = ['SimNodeConfig', 'SeaKingSimNode', 'main']


@dataclass(frozen=True)
class SimNodeConfig(SimConfig, PacingConfig):
    """Simulator settings plus how the node publishes them (pace and stamps: :class:`PacingConfig`)."""

    world_frame: str = setting('world', 'frame of truth, odometry and tracks', read_only=True)
    sensor_frame: str = setting('sonar', 'frame of the sectors (the sonar head)', read_only=True)
    fan_size: int = setting(512, 'longer side of /sonar/fan', unit='px', low=16, high=4096, read_only=True)
    fan_dynamic_range_db: float = setting(30.0, 'grey scale of /sonar/fan above the median', unit='dB',
                                          low=1.0, high=120.0)
    publish_projected: bool = setting(False, 'also publish every sector as marine_acoustic_msgs/ProjectedSonarImage '
                                      'on sonar_image, as an imaging-sonar driver does (for projected_sonar_adapter; '
                                      'needs marine_acoustic_msgs built)', read_only=True)


class SeaKingSimNode(Node):
    """Runs a :class:`Simulator` and publishes its sectors."""

    #: Parameters that may change while running; the sensor and scene are fixed at start-up.
    MUTABLE = {'rate', 'clutter_lambda', 'snr_db', 'fan_dynamic_range_db'}

    def __init__(self, **kwargs) -> None:
        super().__init__('seaking_sim', **kwargs)
        # The scenario and sensor preset decide every other default, so they are read first.
        settings = {s.name: s for s in SimNodeConfig.settings()}
        scenario = declare_choice(self, settings['scenario'], 'scenario2', tuple(SCENARIOS))
        sensors = SCENARIOS[scenario].sensors
        preset = declare_choice(self, settings['preset'], sensors[0], sensors)
        self.params = ConfigParameters(self, SimNodeConfig.for_scenario(scenario, preset), on_change=self._on_change,
                                       skip=('scenario', 'preset'), mutable=self.MUTABLE)
        c = self.config = self.params.config
        self.sim = Simulator(c, np.random.default_rng(c.seed))
        self.get_logger().info(describe(c))
        self.pace, reliable = Pacer(c, self.sim.sensor.next_time), output_profile(10)
        self.pub_sector = self.create_publisher(Image, 'sonar/sector', reliable)
        self.pub_info = self.create_publisher(LaserScan, 'sonar/sector_info', reliable)
        self.pub_fan = self.create_publisher(Image, 'sonar/fan', QoSProfile(depth=1))
        self.pub_truth = self.create_publisher(PointCloud2, 'sonar/truth', reliable)
        self.pub_odom = self.create_publisher(Odometry, 'platform/odometry', reliable)
        self.pub_projected = self._projected_publisher() if c.publish_projected else None
        im = c.imaging   # what ping_info says of an imaging head (0: unknown, for the scanning sensors)
        self._ping_info = ({'sound_speed': im.sound_speed, 'frequency': im.frequency_khz * 1e3,
                            'beam_width': math.radians(im.beam_width_deg)} if c.is_imaging else {})
        self.canvas, self.sectors = PolarCanvas.with_size(self.sim.sensor.coverage(), c.fan_size), 0
        self.gate = SubscriberGate(self, (self.pub_sector, self.pub_info), (self.pub_sector, self.pub_info,
                                   self.pub_truth, self.pub_odom), c.wait_for_subscribers, c.start_settle_time)
        self.diag = StageDiagnostics('seaking_sim: simulation', what='sector')
        self.diag.idle = 'waiting for subscribers'
        self.pub_diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self.sim_time: float | None = None
        self.sim_clock = SimClock(self, c.clock_period, self.report_now) if c.publish_clock else None
        self.create_timer(1.0, self.report_now)
        self.timer = self._timer(c.rate)

    def _projected_publisher(self):
        """The ``sonar_image`` publisher, or None (with the reason logged) without marine_acoustic_msgs."""
        try:
            from marine_acoustic_msgs.msg import ProjectedSonarImage
        except ImportError:
            self.get_logger().error('publish_projected: marine_acoustic_msgs is not importable (build it with '
                                    '`python -m sonar_tracking.cli.build_interfaces`); publishing the sector '
                                    'topics only')
            return None
        return self.create_publisher(ProjectedSonarImage, 'sonar_image', output_profile(10))

    def _timer(self, rate: float):
        return self.create_timer(0.0 if rate == 0 else 0.005, self._tick)

    def _on_change(self, old: SimNodeConfig, new: SimNodeConfig) -> None:
        if new.rate != old.rate:
            self.timer.cancel()
            self.timer = self._timer(new.rate)
        if new.clutter_lambda != old.clutter_lambda:
            self.sim.set_clutter_lambda(new.clutter_lambda)
        if new.snr_db != old.snr_db:
            self.sim.set_snr_db(new.snr_db)
        self.config = new
        self.pace.anchor(self.sim.sensor.next_time, new.rate)

    def _tick(self) -> None:
        if self.sectors == 0:
            # With publish_clock, the first sector waits for the clock's claim, so /clock covers every stamp.
            claiming = self.sim_clock is not None and self.sim_clock.state == 'claiming'
            if claiming or not self.gate.ready():
                self.pace.anchor(self.sim.sensor.next_time)
                if self.sim_clock is not None:   # simulated time stands at the first ping while we wait
                    self.sim_clock.advance(self.pace.stamp_ns(self.sim.sensor.next_time))
                time.sleep(0.01)  # a zero-period timer would spin the CPU while we wait
                return
            if self.config.wait_for_subscribers:
                self.get_logger().info(f'starting; subscribers: {self.gate.describe()}')
            self.diag.idle = None
        if self.config.rate == 0:
            self._publish_next()
            self.pub_sector.wait_for_all_acked(Duration(seconds=1.0))
            return
        while self.pace.due(self.sim.sensor.next_time) and self._publish_next():
            pass
        self._advance_clock()

    def _advance_clock(self) -> None:
        """Move /clock to the simulated time now (at rate 0 it moves with the sectors only)."""
        now = self.pace.sim_now()
        if self.sim_clock is not None and now is not None and not self.sim.finished:
            self.sim_clock.advance(self.pace.stamp_ns(now))

    def _publish_next(self) -> bool:
        started = time.perf_counter()
        sector = self.sim.next_sector()
        if sector is None:
            self.timer.cancel()
            done = (f'scenario {self.config.scenario} finished after {self.sectors} sectors '
                    f'({self.sim.scene.duration:g} s of simulated time)')
            self.get_logger().info(done)
            self.diag.idle = done
            self.report_now()
            if self.config.shutdown_when_done:
                raise SystemExit(0)
            return False
        self._publish(sector)
        self.sectors += 1
        self.sim_time = sector.stamp
        self.diag.done(started)
        if self.sectors == 1:
            self.report_now()   # started
        return True

    def _publish(self, s: SimSector) -> None:
        c = self.config
        ns, world, sonar = self.pace.stamp_ns(s.stamp), c.world_frame, c.sensor_frame
        if self.sim_clock is not None:   # /clock reaches a stamp before any message carries it
            self.sim_clock.advance(ns)
        self.pub_sector.publish(ma.array_to_image(s.amplitudes, stamp_ns=ns, frame_id=sonar))
        self.pub_info.publish(ma.geometry_to_scan(s.geometry, amplitudes=s.amplitudes, stamp_ns=ns, frame_id=sonar))
        if self.pub_projected is not None:
            self.pub_projected.publish(ma.sector_to_projected(s.amplitudes, s.geometry, ns, sonar, **self._ping_info))
        self.pub_truth.publish(ma.array_to_cloud(self.sim.truth_records(s.stamp), stamp_ns=ns, frame_id=world))
        _, _, _, vx, vy = self.sim.scene.platform_pose(s.stamp)
        self.pub_odom.publish(pose_to_odometry(*s.pose, vx, vy, stamp_ns=ns, frame_id=world, child_frame_id=sonar))
        if self.pub_fan.get_subscription_count() > 0:   # painting is most of the cost: only for a viewer
            self.canvas.paint(self.sim.linear(s.amplitudes), s.geometry)
            fan = to_mono8(self.canvas.image, c.fan_dynamic_range_db)
            self.pub_fan.publish(ma.array_to_image(fan, 'mono8', stamp_ns=ns, frame_id=sonar))

    def report_now(self) -> None:
        """Publish the diagnostics (once a second, and at once when the state changes)."""
        c = self.config
        if self.diag.idle is not None and self.sectors == 0:
            claiming = self.sim_clock is not None and self.sim_clock.state == 'claiming'
            self.diag.idle = 'waiting for ' + ('the claim of /clock' if claiming else
                                               f'subscribers ({self.gate.describe()})')
        outputs = [self.pub_sector, self.pub_info, self.pub_fan, self.pub_truth, self.pub_odom, self.pub_projected]
        self.diag.listeners = {p.topic_name: p.get_subscription_count() for p in outputs if p is not None}
        clock = 'off' if self.sim_clock is None else self.sim_clock.describe()
        refused = self.sim_clock is not None and self.sim_clock.state == 'refused'
        self.diag.condition('clock', f'clock {clock}' if refused else None, DiagnosticStatus.WARN)
        no_projected = c.publish_projected and self.pub_projected is None
        self.diag.condition('projected', 'publish_projected: marine_acoustic_msgs not importable' if no_projected
                            else None, DiagnosticStatus.WARN)
        self.diag.values = {'scenario': c.scenario, 'preset': c.preset, 'rate': f'{c.rate:g}',
                            'stamps': 'wall' if self.pace.wall_stamps else 'sim', 'sectors': str(self.sectors),
                            'sim_time_s': 'nan' if self.sim_time is None else f'{self.sim_time:.3f}', 'clock': clock}
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking seaking_sim``."""
    return run_node(SeaKingSimNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

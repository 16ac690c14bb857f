"""``seaking_sim``: the simulated scanning sonar (SeaKing 675/325 kHz or the harbour sonar).

Publishes, per sector (DESIGN §4): ``sonar/sector`` (32FC1 amplitudes; mono8 dB counts with
``output.coding: db``, as the ``*_structured`` scenarios do), ``sonar/sector_info`` (its geometry,
same header), ``sonar/fan`` (mono8 picture, painted only while someone listens), ``sonar/truth`` and
``platform/odometry``; and ``/clock`` whenever it stamps with simulated time. ``rate`` sets the
pace (0: as fast as the reliable readers acknowledge; falling behind never skips a sector) and
``stamps`` the clock the messages carry (:class:`~sonar_tracking.ros.pacing.Pacer`): ``wall``,
``sim`` (from ``stamp_offset``; the same seed gives the same messages bit for bit), or ``auto``
(``wall`` when starting at ``rate`` 1).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, LaserScan, PointCloud2

import sonar_tracking.msgs as ma
from sonar_tracking.core.config import setting
from sonar_tracking.core.fan import PolarCanvas, to_mono8
from sonar_tracking.msgs.odometry import pose_to_odometry
from sonar_tracking.ros import (
    CLOCK_TOPIC,
    ConfigParameters,
    Pacer,
    PacingConfig,
    SubscriberGate,
    declare_choice,
    output_profile,
    run_node,
)
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
        clock = c.publish_clock or not self.pace.wall_stamps
        self.pub_clock = self.create_publisher(Clock, CLOCK_TOPIC, 10) if clock else None
        self.canvas, self.sectors = PolarCanvas.with_size(self.sim.sensor.coverage(), c.fan_size), 0
        self.gate = SubscriberGate(self, (self.pub_sector, self.pub_info), (self.pub_sector, self.pub_info,
                                   self.pub_truth, self.pub_odom), c.wait_for_subscribers, c.start_settle_time)
        self.timer = self._timer(c.rate)

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
            if not self.gate.ready():
                self.pace.anchor(self.sim.sensor.next_time)
                time.sleep(0.01)  # a zero-period timer would spin the CPU while we wait
                return
            if self.config.wait_for_subscribers:
                self.get_logger().info(f'starting; subscribers: {self.gate.describe()}')
        if self.config.rate == 0:
            self._publish_next()
            self.pub_sector.wait_for_all_acked(Duration(seconds=1.0))
            return
        while self.pace.due(self.sim.sensor.next_time) and self._publish_next():
            pass

    def _publish_next(self) -> bool:
        sector = self.sim.next_sector()
        if sector is None:
            self.timer.cancel()
            self.get_logger().info(f'scenario {self.config.scenario} finished after {self.sectors} sectors '
                                   f'({self.sim.scene.duration:g} s of simulated time)')
            if self.config.shutdown_when_done:
                raise SystemExit(0)
            return False
        self._publish(sector)
        self.sectors += 1
        return True

    def _publish(self, s: SimSector) -> None:
        c = self.config
        ns, world, sonar = self.pace.stamp_ns(s.stamp), c.world_frame, c.sensor_frame
        self.pub_sector.publish(ma.array_to_image(s.amplitudes, stamp_ns=ns, frame_id=sonar))
        self.pub_info.publish(ma.geometry_to_scan(s.geometry, amplitudes=s.amplitudes, stamp_ns=ns, frame_id=sonar))
        self.pub_truth.publish(ma.array_to_cloud(self.sim.truth_records(s.stamp), stamp_ns=ns, frame_id=world))
        _, _, _, vx, vy = self.sim.scene.platform_pose(s.stamp)
        self.pub_odom.publish(pose_to_odometry(*s.pose, vx, vy, stamp_ns=ns, frame_id=world, child_frame_id=sonar))
        if self.pub_fan.get_subscription_count() > 0:   # painting is most of the cost: only for a viewer
            self.canvas.paint(self.sim.linear(s.amplitudes), s.geometry)
            fan = to_mono8(self.canvas.image, c.fan_dynamic_range_db)
            self.pub_fan.publish(ma.array_to_image(fan, 'mono8', stamp_ns=ns, frame_id=sonar))
        if self.pub_clock is not None:
            self.pub_clock.publish(Clock(clock=ma.ns_to_stamp(ns)))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking seaking_sim``."""
    return run_node(SeaKingSimNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

"""``seaking_sim``: the simulated scanning sonar (SeaKing 675/325 kHz or the harbour sonar).

Publishes, per sector (DESIGN §4): ``sonar/sector`` (32FC1 amplitudes; mono8 dB counts with
``output.coding: db``, as the ``*_structured`` scenarios do), ``sonar/sector_info``
(its geometry, same header), ``sonar/fan`` (mono8 picture, painted only while someone listens),
``sonar/truth`` and ``platform/odometry``; and ``/clock`` whenever it stamps with simulated time.

``rate`` sets the pace: 1 = real time, 0 = as fast as the subscribers acknowledge each sector
(reliable QoS). Falling behind never skips a sector. ``stamps`` says which clock the messages carry,
so they agree with the rest of the system:

* ``wall``: the wall clock at which the sector is due (``ros2 topic delay`` reads about 0);
* ``sim``: simulated time from ``stamp_offset``, with ``/clock`` published so ``use_sim_time``
  nodes and bags agree; the same seed gives the same messages bit for bit;
* ``auto`` (default): ``wall`` when the simulator starts at ``rate`` 1, ``sim`` otherwise.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image, LaserScan, PointCloud2

import msg_adapters as ma
from msg_adapters.odometry import pose_to_odometry
from sonar_tracking.core.config import setting
from sonar_tracking.core.fan import PolarCanvas, to_mono8
from sonar_tracking.core.intensity import decode
from sonar_tracking.core.sim import SimConfig, SimSector, Simulator, describe
from sonar_tracking.core.sim.presets import SCENARIOS
from sonar_tracking.ros import (CLOCK_TOPIC, ConfigParameters, SubscriberGate, descriptor_for, output_profile,
                                 run_node, start_value)

__all__ = ['SimNodeConfig', 'SeaKingSimNode', 'main']


@dataclass(frozen=True)
class SimNodeConfig(SimConfig):
    """Simulator settings plus how the node publishes them."""

    rate: float = setting(1.0, 'pace: 1 = real time, 2 = twice as fast, 0 = as fast as subscribers take it',
                          low=0.0, high=1e4)
    world_frame: str = setting('world', 'frame of truth, odometry and tracks', read_only=True)
    sensor_frame: str = setting('sonar', 'frame of the sectors (the sonar head)', read_only=True)
    stamps: str = setting('auto', 'clock of the stamps: wall, sim (simulated time, with /clock), or auto (wall when '
                          'starting at rate 1, else sim)', choices=('auto', 'wall', 'sim'), read_only=True)
    stamp_offset: float = setting(0.0, 'stamp of the scenario start with sim stamps', unit='s', low=0.0, high=4e9,
                                  read_only=True)
    fan_size: int = setting(512, 'longer side of /sonar/fan', unit='px', low=16, high=4096, read_only=True)
    fan_dynamic_range_db: float = setting(30.0, 'grey scale of /sonar/fan above the median', unit='dB',
                                          low=1.0, high=120.0)
    publish_clock: bool = setting(False, 'publish /clock with wall stamps too (it is always published with sim '
                                  'stamps)', read_only=True)
    shutdown_when_done: bool = setting(False, 'exit once the scenario has ended', read_only=True)
    wait_for_subscribers: int = setting(0, 'start once /sonar/sector and /sonar/sector_info have this many '
                                        'subscribers and every subscriber in the graph is connected (0 = at once)',
                                        low=0, high=1000, read_only=True)
    start_settle_time: float = setting(1.0, 'with wait_for_subscribers: how long the graph must stay connected '
                                       'before the start (3.5 s for subscribers of tools that announce every 3 s)',
                                       unit='s', low=0.0, high=60.0, read_only=True)


class SeaKingSimNode(Node):
    """Runs a :class:`Simulator` and publishes its sectors."""

    #: Parameters that may change while running; the sensor and scene are fixed at start-up.
    MUTABLE = {'rate', 'clutter_lambda', 'snr_db', 'fan_dynamic_range_db'}

    def __init__(self, **kwargs) -> None:
        super().__init__('seaking_sim', **kwargs)
        log = self.get_logger()
        # The scenario and sensor preset decide every other default, so they are read first.
        scenario = self._declare_choice('scenario', 'scenario2', tuple(SCENARIOS))
        preset = self._declare_choice('preset', SCENARIOS[scenario].sensors[0], SCENARIOS[scenario].sensors)
        base = SimNodeConfig.for_scenario(scenario, preset)
        self.params = ConfigParameters(self, base, on_change=self._on_change, skip=('scenario', 'preset'),
                                       mutable=self.MUTABLE)
        self.config: SimNodeConfig = self.params.config
        self.sim = Simulator(self.config, np.random.default_rng(self.config.seed))
        log.info(describe(self.config))

        self.wall_stamps = self.config.stamps == 'wall' or (self.config.stamps == 'auto' and self.config.rate == 1.0)
        reliable = output_profile(10)
        self.pub_sector = self.create_publisher(Image, 'sonar/sector', reliable)
        self.pub_info = self.create_publisher(LaserScan, 'sonar/sector_info', reliable)
        self.pub_fan = self.create_publisher(Image, 'sonar/fan', QoSProfile(depth=1))
        self.pub_truth = self.create_publisher(PointCloud2, 'sonar/truth', reliable)
        self.pub_odom = self.create_publisher(Odometry, 'platform/odometry', reliable)
        clock = self.config.publish_clock or not self.wall_stamps
        self.pub_clock = self.create_publisher(Clock, CLOCK_TOPIC, 10) if clock else None

        self.canvas = self._make_canvas()
        self.sectors = 0
        c = self.config
        self.gate = SubscriberGate(self, (self.pub_sector, self.pub_info), (self.pub_sector, self.pub_info,
                                   self.pub_truth, self.pub_odom), c.wait_for_subscribers, c.start_settle_time)
        self._anchor()
        self.timer = self.create_timer(0.0 if self.config.rate == 0 else 0.005, self._tick)

    def _declare_choice(self, name: str, default: str, choices: tuple[str, ...]) -> str:
        s = next(s for s in SimNodeConfig.settings() if s.name == name)
        value = start_value(self, s, default)
        if value not in choices:
            self.get_logger().error(f'parameter {name}: {value!r} is not one of {list(choices)}; using {default!r}')
            value = default
        return self.declare_parameter(name, value, descriptor_for(s), ignore_override=True).value

    def _make_canvas(self) -> PolarCanvas:
        return PolarCanvas.with_size(self.sim.sensor.coverage(), self.config.fan_size)

    def _anchor(self) -> None:
        """Tie the next sector's simulation time to now (at start and when ``rate`` changes)."""
        self._wall0 = time.monotonic()
        self._epoch0_ns = time.time_ns()
        self._sim0 = self.sim.sensor.next_time

    def _on_change(self, old: SimNodeConfig, new: SimNodeConfig) -> None:
        if new.rate != old.rate:
            self.timer.cancel()
            self.timer = self.create_timer(0.0 if new.rate == 0 else 0.005, self._tick)
        if new.clutter_lambda != old.clutter_lambda:
            self.sim.set_clutter_lambda(new.clutter_lambda)
        if new.snr_db != old.snr_db:
            self.sim.set_snr_db(new.snr_db)
        self.config = new
        self._anchor()

    def _tick(self) -> None:
        if self.sectors == 0:
            if not self.gate.ready():
                self._anchor()
                time.sleep(0.01)  # a zero-period timer would spin the CPU while we wait
                return
            if self.config.wait_for_subscribers:
                self.get_logger().info(f'starting; subscribers: {self.gate.describe()}')
        rate = self.config.rate
        if rate == 0:
            self._publish_next()
            self.pub_sector.wait_for_all_acked(Duration(seconds=1.0))
            return
        due = self._wall0 + (self.sim.sensor.next_time - self._sim0) / rate
        while time.monotonic() >= due:
            if not self._publish_next():
                return
            due = self._wall0 + (self.sim.sensor.next_time - self._sim0) / rate

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

    def _stamp_ns(self, sim_t: float) -> int:
        """The stamp of simulated time ``sim_t``: the wall time it is due at, or simulated time."""
        if not self.wall_stamps:
            return int(round((self.config.stamp_offset + sim_t) * 1e9))
        if self.config.rate == 0:
            return time.time_ns()
        return self._epoch0_ns + int(round((sim_t - self._sim0) / self.config.rate * 1e9))

    def _publish(self, s: SimSector) -> None:
        c = self.config
        stamp_ns = self._stamp_ns(s.stamp)
        self.pub_sector.publish(ma.array_to_image(s.amplitudes, stamp_ns=stamp_ns, frame_id=c.sensor_frame))
        self.pub_info.publish(ma.geometry_to_scan(s.geometry, amplitudes=s.amplitudes, stamp_ns=stamp_ns,
                                                  frame_id=c.sensor_frame))
        ids, states = self.sim.truth(s.stamp)
        truth = np.zeros(len(ids), ma.TRUTH_DTYPE)
        truth['target_id'] = ids
        for i, name in enumerate(('x', 'y', 'vx', 'vy')):
            truth[name] = states[:, i]
        self.pub_truth.publish(ma.array_to_cloud(truth, stamp_ns=stamp_ns, frame_id=c.world_frame))
        _, _, _, vx, vy = self.sim.scene.platform_pose(s.stamp)
        self.pub_odom.publish(pose_to_odometry(*s.pose, vx, vy, stamp_ns=stamp_ns, frame_id=c.world_frame,
                                               child_frame_id=c.sensor_frame))
        if self.pub_fan.get_subscription_count() > 0:   # painting is most of the cost: only for a viewer
            self.canvas.paint(s.amplitudes if c.output.coding != 'db' else
                              decode(s.amplitudes, 'db', db_span=c.output.db_span, full_scale=255.0), s.geometry)
            fan = to_mono8(self.canvas.image, c.fan_dynamic_range_db)
            self.pub_fan.publish(ma.array_to_image(fan, 'mono8', stamp_ns=stamp_ns, frame_id=c.sensor_frame))
        if self.pub_clock is not None:
            self.pub_clock.publish(Clock(clock=ma.ns_to_stamp(stamp_ns)))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run sonar_tracking seaking_sim``."""
    return run_node(SeaKingSimNode, args)


if __name__ == '__main__':
    raise SystemExit(main())

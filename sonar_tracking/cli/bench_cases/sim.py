"""Simulator speed (issue: scanning-sonar simulator): core scans and the node at full speed."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np

from sonar_tracking import process
from sonar_tracking.cli.bench import Case, register


def _seaking_full_turn():
    from sonar_tracking.sim import SimConfig, Simulator
    cfg = SimConfig.for_scenario('sea_trial', 'seaking675', sector_size=400, **{
        'seaking.scan_min_deg': -180.0, 'seaking.scan_max_deg': 180.0, 'seaking.step_deg': 0.9,
        'seaking.n_bins': 600, 'seaking.range_max': 50.0})
    sim = Simulator(cfg, np.random.default_rng(0))
    sonar, scene, rng = sim.sensor, sim.scene, sim.noise_rng
    assert cfg.seaking.n_positions == 400
    return lambda: sonar.next_sector(scene, rng)


def _harbour_scan(scenario: str = 'scenario2'):
    from sonar_tracking.sim import SimConfig, Simulator
    sim = Simulator(SimConfig.for_scenario(scenario), np.random.default_rng(0))
    sonar, scene, rng = sim.sensor, sim.scene, sim.noise_rng
    return lambda: sonar.next_sector(scene, rng)


def _fan_paint(scenario: str):
    """``/sonar/fan`` painting of consecutive sectors on the node's 512 px canvas (maps cached after a sweep)."""
    def make():
        from sonar_tracking.core.fan import PolarCanvas
        from sonar_tracking.sim import SimConfig, Simulator
        sim = Simulator(SimConfig.for_scenario(scenario), np.random.default_rng(0))
        canvas = PolarCanvas.with_size(sim.sensor.coverage(), 512)
        sectors = [sim.next_sector() for _ in range(40)]
        for s in sectors:
            canvas.paint(s.amplitudes, s.geometry)
        state = {'k': 0}

        def paint() -> None:
            s = sectors[state['k'] % len(sectors)]
            state['k'] += 1
            canvas.paint(s.amplitudes, s.geometry)
        return paint
    return make


SIM_SECONDS = 100.0


def _node_rate0():
    """Wall time from the first to the last sector of 100 simulated seconds (Scenario 2, rate 0)."""
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, LaserScan, PointCloud2

    from sonar_tracking.ros.runtime import configure_dds, private_domain

    def measure() -> float:
        configure_dds()
        private_domain()   # another pipeline on this machine must not answer for ours
        rclpy.init()
        node = rclpy.create_node('bench_sim_probe')
        qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
        stamps = []
        node.create_subscription(Image, 'sonar/sector', lambda m: stamps.append(time.monotonic()), qos)
        node.create_subscription(LaserScan, 'sonar/sector_info', lambda m: None, qos)
        node.create_subscription(PointCloud2, 'sonar/truth', lambda m: None, qos)
        child = subprocess.Popen([sys.executable, '-m', 'sonar_tracking.nodes.seaking_sim', '--ros-args',
                                  '-p', 'scenario:=scenario2', '-p', 'rate:=0.0', '-p', 'wait_for_subscribers:=1',
                                  '-p', 'shutdown_when_done:=true'], start_new_session=True,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 preexec_fn=process.child_dies_with_parent())
        try:
            deadline = time.monotonic() + 120
            while (child.poll() is None or len(stamps) < 100) and time.monotonic() < deadline:
                rclpy.spin_once(node, timeout_sec=0.05)
        finally:
            if child.poll() is None:
                os.killpg(child.pid, signal.SIGINT)
                child.wait(10)
            node.destroy_node()
            rclpy.try_shutdown()
        if len(stamps) < 100:
            raise RuntimeError(f'only {len(stamps)} of 100 sectors arrived')
        # 99 sector intervals of 1 s of simulated time each.
        return (stamps[-1] - stamps[0]) * SIM_SECONDS / 99.0
    return measure


register(Case(name='sim.seaking_full_turn', group='sim', make=_seaking_full_turn, limit_s=0.050,
              description='SeaKing 360 deg turn, 400 steps x 600 bins, two towed targets (core)', repeats=20))
register(Case(name='sim.harbour_scan', group='sim', make=_harbour_scan, limit_s=0.005,
              description='harbour scan, 86 x 69 cells, Scenario 2 (core)'))
register(Case(name='sim.harbour_scan_structured', group='sim', make=lambda: _harbour_scan('scenario2_structured'),
              limit_s=0.005, description='harbour scan with quay, breakwater, piles, seabed band, ringdown (core)'))
register(Case(name='sim.fan_paint_harbour', group='sim', make=_fan_paint('scenario2'), limit_s=0.002,
              description='/sonar/fan paint of a harbour scan, 512 px canvas (core.fan)'))
register(Case(name='sim.fan_paint_seaking', group='sim', make=_fan_paint('fls8'), limit_s=0.002,
              description='/sonar/fan paint of a 10-ping SeaKing sector, tank, 512 px canvas (core.fan)'))
register(Case(name='sim.node_rate0', group='sim', make=_node_rate0, self_timed=True, repeats=3,
              limit_s=SIM_SECONDS / 20.0, description='seaking_sim node, rate 0, 100 s of Scenario 2 over DDS',
              derived=lambda r: {'x_real_time': SIM_SECONDS / r.median_s}))

"""Sector-to-/tracks latency through the running nodes (issue: the whole stack).

``active_detector`` and ``imm_ipda_tracker`` run as their own processes; this process publishes
harbour sectors (ESC Scenario 1) at a fixed rate (100 at 10 Hz; 600 at 60 Hz, the rate a fast
harbour sonar or a replay at 6x needs) and times, for each, the interval from publishing the sector
pair to receiving the ``/tracks`` message with its stamp. Every latency is a sample; a sector
without its ``/tracks`` fails the case, so a case that finishes sustained its rate.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np

from sonar_tracking import process
from sonar_tracking.cli.bench import Case, register


def wait_for_pipeline(node, sector_publisher, timeout: float) -> None:
    """Spin ``node`` until the detector reads ``sector_publisher``, the tracker reads ``/detections`` and
    publishes ``/tracks`` (or ``timeout`` s pass), then one more second for the matches to settle."""
    import rclpy
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not (
            sector_publisher.get_subscription_count() and node.count_subscribers('/detections')
            and node.count_publishers('/tracks')):
        rclpy.spin_once(node, timeout_sec=0.05)
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)


def _latency(n_sectors: int = 100, rate_hz: float = 10.0):
    def measure() -> list[float]:
        from sonar_tracking.ros.runtime import configure_dds, private_domain
        configure_dds()
        private_domain()   # another pipeline on this machine must not answer for ours
        import rclpy
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Image, LaserScan, PointCloud2

        import sonar_tracking.msgs as ma
        from sonar_tracking.resources import config_path
        from sonar_tracking.sim import SimConfig, Simulator

        sim = Simulator(SimConfig.for_scenario('scenario1', duration=0.0), np.random.default_rng(0))
        sectors = [sim.next_sector() for _ in range(n_sectors)]
        msgs = [(ma.array_to_image(s.amplitudes, stamp_ns=int(s.stamp * 1e9), frame_id='sonar'),
                 ma.geometry_to_scan(s.geometry, stamp_ns=int(s.stamp * 1e9), frame_id='sonar')) for s in sectors]
        procs = [subprocess.Popen([sys.executable, '-m', f'sonar_tracking.nodes.{name}', '--ros-args', *args],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                                  preexec_fn=process.child_dies_with_parent())
                 for name, args in (('active_detector', ['--params-file', str(config_path('active_detector.yaml'))]),
                                    ('imm_ipda_tracker', ['--params-file', str(config_path('imm_ipda.yaml'))]))]
        rclpy.init()
        node = rclpy.create_node('bench_latency')
        qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
        pub_img = node.create_publisher(Image, 'sonar/sector', qos)
        pub_info = node.create_publisher(LaserScan, 'sonar/sector_info', qos)
        sent, received = {}, {}
        node.create_subscription(PointCloud2, 'tracks',
                                 lambda m: received.setdefault(ma.header_ns(m), time.perf_counter()), qos)
        try:
            wait_for_pipeline(node, pub_img, 60.0)
            for img, info in msgs:
                stamp = ma.header_ns(img)
                sent[stamp] = time.perf_counter()
                pub_img.publish(img)
                pub_info.publish(info)
                next_at = sent[stamp] + 1.0 / rate_hz
                while time.perf_counter() < next_at:
                    rclpy.spin_once(node, timeout_sec=max(0.0, next_at - time.perf_counter()))
            end = time.monotonic() + 2.0
            while time.monotonic() < end and len(received) < len(sent):
                rclpy.spin_once(node, timeout_sec=0.05)
        finally:
            for p in procs:
                os.killpg(p.pid, signal.SIGINT)
                p.wait(10)
            node.destroy_node()
            rclpy.try_shutdown()
        lost = len(sent) - len(received)
        if lost:
            raise RuntimeError(f'{lost} of {len(sent)} sectors got no /tracks message')
        return [received[s] - sent[s] for s in sent]
    return measure


register(Case(name='pipeline.sector_to_tracks', group='pipeline', make=_latency, self_timed=True, repeats=1,
              limit_s=0.030, description='sector pair published -> /tracks received, through active_detector and '
              'imm_ipda_tracker processes (100 sectors at 10 Hz)'))
register(Case(name='pipeline.sector_to_tracks_60hz', group='pipeline', make=lambda: _latency(600, 60.0),
              self_timed=True, repeats=1, limit_s=0.020, description='as pipeline.sector_to_tracks, 600 sectors at '
              '60 Hz: every sector tracked (sustained) with the median latency under the limit'))

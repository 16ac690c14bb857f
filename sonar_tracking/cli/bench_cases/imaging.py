"""An imaging sonar in real time over DDS (issue: imaging sonars): 512 beams x 1000 bins at 20 Hz
through ``active_detector`` and ``imm_ipda_tracker``.

Both nodes run as their own processes with the Oculus M750d preset (``config/sensors/oculus_m750d.yaml``:
CA-CFAR with ESC, connected blobs, structure rejection; the IMM-IPDA tracker at frame rate), reading
reliably. This process publishes frames of the ``imaging_diver`` scenario rendered once before the
run (100 frames, replayed in a loop with fresh stamps: the simulator's own cost is not counted) as the
sensor sends them: ``mono8`` images of 8-bit log counts, 512 x 1000 bytes = 0.5 MB a frame, with
their ``LaserScan`` geometry and the platform's odometry, reliable, at 20 Hz. Each frame is timed from
publishing its sector to receiving the ``/tracks`` message with its stamp; every latency is a sample.

Reported beside the latency: frames sent, frames without ``/tracks`` (dropped), the 99th percentile,
and each node's resident memory at minute 2 (or a fifth of a shorter run) and at the end.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np

from sonar_tracking import process
from sonar_tracking.cli.bench import Case, Result, register
from sonar_tracking.cli.bench_cases.pipeline import wait_for_pipeline

_STATS: dict[str, dict] = {}
RATE_HZ = 20.0


def _rss_mb(pid: int) -> float:
    """Resident memory of a process [MB] (VmRSS), NaN once it is gone."""
    try:
        with open(f'/proc/{pid}/status') as f:
            return next(float(line.split()[1]) for line in f if line.startswith('VmRSS:')) / 1024.0
    except (OSError, StopIteration):
        return float('nan')


def _frames(n: int) -> list:
    """``n`` frames of ``imaging_diver`` on the Oculus preset as (image, scan, odometry) messages."""
    import sonar_tracking.msgs as ma
    from sonar_tracking.msgs.odometry import pose_to_odometry
    from sonar_tracking.sim import SimConfig, Simulator
    sim = Simulator(SimConfig.for_scenario('imaging_diver', 'oculus_m750d'), np.random.default_rng(0))
    out = []
    for _ in range(n):
        s = sim.next_sector()
        ns = int(s.stamp * 1e9)
        _, _, _, vx, vy = sim.scene.platform_pose(s.stamp)
        out.append((ma.array_to_image(s.amplitudes, stamp_ns=ns, frame_id='sonar'),
                    ma.geometry_to_scan(s.geometry, amplitudes=s.amplitudes, stamp_ns=ns, frame_id='sonar'),
                    pose_to_odometry(*s.pose, vx, vy, stamp_ns=ns, frame_id='world', child_frame_id='sonar')))
    return out


def _pipeline(name: str, minutes: float):
    def measure() -> list[float]:
        from sonar_tracking.ros.runtime import configure_dds, private_domain
        configure_dds()
        private_domain()   # another pipeline on this machine must not answer for ours
        import rclpy
        from nav_msgs.msg import Odometry
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Image, LaserScan, PointCloud2

        import sonar_tracking.msgs as ma
        from sonar_tracking.resources import config_path

        frames = _frames(100)
        preset = str(config_path('sensors/oculus_m750d.yaml'))
        nodes = {'active_detector': ['-p', 'intensity.coding:=db', '-p', 'intensity.db_span:=60.0'],
                 'imm_ipda_tracker': []}
        procs = {n: subprocess.Popen([sys.executable, '-m', f'sonar_tracking.nodes.{n}', '--ros-args',
                                      '--params-file', preset, '-p', 'input_qos:=reliable', *args],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                                     preexec_fn=process.child_dies_with_parent())
                 for n, args in nodes.items()}
        rclpy.init()
        node = rclpy.create_node('bench_imaging')
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE)
        pub_img = node.create_publisher(Image, 'sonar/sector', qos)
        pub_info = node.create_publisher(LaserScan, 'sonar/sector_info', qos)
        pub_odom = node.create_publisher(Odometry, 'platform/odometry', qos)
        sent: dict[int, float] = {}
        received: dict[int, float] = {}
        node.create_subscription(PointCloud2, 'tracks',
                                 lambda m: received.setdefault(ma.header_ns(m), time.perf_counter()), qos)
        rss: dict[str, tuple[float, float]] = {}
        try:
            wait_for_pipeline(node, pub_img, 120.0)
            total = int(round(minutes * 60.0 * RATE_HZ))
            early = min(int(120 * RATE_HZ), total // 5)
            start = time.perf_counter()
            base_ns = 1_000_000_000
            for k in range(total):
                img, info, odom = frames[k % len(frames)]
                ns = base_ns + int(k * 1e9 / RATE_HZ)
                stamp = ma.ns_to_stamp(ns)
                for msg in (img, info, odom):
                    msg.header.stamp = stamp
                next_at = start + k / RATE_HZ
                while time.perf_counter() < next_at:
                    rclpy.spin_once(node, timeout_sec=max(0.0, next_at - time.perf_counter()))
                sent[ns] = time.perf_counter()
                pub_odom.publish(odom)
                pub_img.publish(img)
                pub_info.publish(info)
                if k == early:
                    rss = {n: (_rss_mb(p.pid), float('nan')) for n, p in procs.items()}
            end = time.monotonic() + 5.0
            while time.monotonic() < end and len(received) < len(sent):
                rclpy.spin_once(node, timeout_sec=0.05)
            rss = {n: (rss.get(n, (float('nan'),))[0], _rss_mb(p.pid)) for n, p in procs.items()}
        finally:
            for p in procs.values():
                os.killpg(p.pid, signal.SIGINT)
                p.wait(30)
            node.destroy_node()
            rclpy.try_shutdown()
        latencies = [received[s] - sent[s] for s in sent if s in received]
        _STATS[name] = {'frames': len(sent), 'dropped': len(sent) - len(latencies),
                        'p99_ms': 1e3 * float(np.percentile(latencies, 99)) if latencies else float('nan'),
                        **{f'{n}_rss_growth_MB': end_mb - early_mb for n, (early_mb, end_mb) in rss.items()},
                        **{f'{n}_rss_MB': end_mb for n, (_, end_mb) in rss.items()}}
        if not latencies:
            raise RuntimeError(f'none of {len(sent)} frames got a /tracks message')
        return latencies
    return measure


def _derived(name: str):
    def derived(r: Result) -> dict:
        return dict(_STATS.get(name, {}))
    return derived


for _name, _minutes, _what in (('pipeline.imaging_20hz', 10.0, '10 minutes'),
                               ('pipeline.imaging_20hz_1min', 1.0, '1 minute')):
    register(Case(name=_name, group='pipeline', make=lambda n=_name, m=_minutes: _pipeline(n, m), self_timed=True,
                  repeats=1, limit_s=0.050, derived=_derived(_name),
                  description=f'512 x 1000 mono8 frames (0.5 MB) at 20 Hz for {_what}, published reliably -> /tracks '
                  'received, through active_detector (Oculus preset: CA-CFAR, ESC, structure) and imm_ipda_tracker '
                  'processes; dropped frames, p99 latency and resident-memory growth beside it'))

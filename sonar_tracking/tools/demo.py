"""``make demo``: the built-in harbour scenario through real ROS 2 nodes, and what came out.

Starts ``seaking_sim`` (ESC paper Scenario 2: a manoeuvring target crossing from clutter rate
lam 1.6 into lam 0.8) as its own process at full speed, listens over DDS like any user's node,
then prints a summary (scans, measured false-alarm and detection rates against ESC eqs. 15-16 at
a reference threshold) and writes a PNG of the echoes, the true track and the clutter statistics.
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sonar_tracking.core.fan import PolarCanvas, to_mono8
from sonar_tracking.core.sim import SimConfig, Simulator, exponential_pd, exponential_pfa
from sonar_tracking.nodes._runtime import configure_dds

__all__ = ['main']


def _collect(scenario: str, timeout: float) -> tuple[list, float]:
    """Run the simulator node; return ``[(stamp_ns, amplitudes, geometry, truth), ...]`` and wall time."""
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, LaserScan, PointCloud2

    import msg_adapters as ma

    rclpy.init()
    node = rclpy.create_node('sonar_demo')
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    pairer, truths, scans = ma.SectorPairer(), {}, []

    def on_pair(pair):
        if pair is not None:
            amps, geom = ma.sector_from_messages(pair.image, pair.info)
            scans.append((pair.stamp_ns, np.array(amps), geom))

    node.create_subscription(Image, '/sonar/sector', lambda m: on_pair(pairer.add_image(m)), qos)
    node.create_subscription(LaserScan, '/sonar/sector_info', lambda m: on_pair(pairer.add_info(m)), qos)
    node.create_subscription(PointCloud2, '/sonar/truth',
                             lambda m: truths.__setitem__(ma.header_ns(m), np.array(ma.cloud_to_array(m))), qos)
    cmd = [sys.executable, '-m', 'sonar_tracking.nodes.seaking_sim', '--ros-args', '-p', f'scenario:={scenario}',
           '-p', 'rate:=0.0', '-p', 'wait_for_subscribers:=1', '-p', 'shutdown_when_done:=true']
    print('$ seaking_sim --ros-args ' + ' '.join(cmd[cmd.index('--ros-args') + 1:]), flush=True)
    child = subprocess.Popen(cmd, start_new_session=True)
    t0, t_first = time.monotonic(), None
    try:
        idle_since = None
        while time.monotonic() - t0 < timeout:
            rclpy.spin_once(node, timeout_sec=0.05)
            if scans and t_first is None:
                t_first = time.monotonic()
            if child.poll() is not None:
                idle_since = idle_since or time.monotonic()
                if time.monotonic() - idle_since > 1.0:
                    break
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGINT)
            child.wait(10)
        wall = time.monotonic() - (t_first or t0)
        node.destroy_node()
        rclpy.try_shutdown()
    out = [(s, a, g, truths.get(s)) for s, a, g in scans]
    return out, wall


def main(argv: list[str] | None = None) -> int:
    """Entry point (``make demo`` runs ``python -m sonar_tracking.tools.demo``)."""
    parser = argparse.ArgumentParser(prog='sonar_demo', description=__doc__.split('\n\n')[0])
    parser.add_argument('--scenario', default='scenario2', choices=('scenario1', 'scenario2'))
    parser.add_argument('--out', type=Path, default=Path('out'))
    parser.add_argument('--timeout', type=float, default=120.0)
    parser.add_argument('--threshold', type=float, default=3.0, help='reference threshold for the rates')
    args = parser.parse_args(argv)
    configure_dds()
    scans, wall = _collect(args.scenario, args.timeout)
    if not scans:
        print('error: no sectors received from seaking_sim', file=sys.stderr)
        return 1
    config = SimConfig.for_scenario(args.scenario)
    sim = Simulator(config, np.random.default_rng(0))  # for the clutter map and sonar pose only
    sonar = sim.sensor
    pose = sim.scene.platform_pose(0.0)[:3]
    lam_cells = np.broadcast_to(sim.scene.lam_at(sonar.cell_centres(pose)), sonar.geometry.shape)
    tau = args.threshold
    g = sonar.geometry
    clutter_hits = {}
    target_hits = []
    for _, amps, geom, truth in scans:
        mask = np.ones(amps.shape, bool)
        if truth is not None and len(truth):
            for rec in truth:
                dx, dy = rec['x'] - pose[0], rec['y'] - pose[1]
                i = int(round((math.hypot(dx, dy) - g.range_min) / g.range_resolution))
                j = int(round((math.atan2(dy, dx) - pose[2] - g.angle_min) / g.angle_increment))
                if 0 <= i < g.n_bins and 0 <= j < g.n_beams:
                    mask[i, j] = False
                    target_hits.append((amps[i, j] > tau, lam_cells[i, j]))
        for lam in np.unique(lam_cells):
            sel = mask & (lam_cells == lam)
            n, k = clutter_hits.get(lam, (0, 0))
            clutter_hits[lam] = (n + int(sel.sum()), k + int((amps[sel] > tau).sum()))
    sim_seconds = (scans[-1][0] - scans[0][0]) / 1e9 + config.harbour.scan_period
    print()
    print(f'seaking_sim, {config.scenario}: {len(scans)} scans of {g.n_bins} x {g.n_beams} cells received over DDS '
          f'in {wall:.2f} s ({sim_seconds / max(wall, 1e-9):.0f}x real time)')
    print(f'{"":28s}{"measured":>12s}{"expected":>12s}{"cells":>10s}')
    for lam, (n, k) in sorted(clutter_hits.items()):
        print(f'  P_fa, lam {lam:.1f}, tau {tau:g}     {k / n:12.5f}{float(exponential_pfa(lam, tau)):12.5f}{n:10d}')
    for lam in sorted({lam for _, lam in target_hits}):
        hits = [h for h, l_ in target_hits if l_ == lam]
        print(f'  P_D, lam {lam:.1f}, {config.snr_db:g} dB      {np.mean(hits):12.3f}'
              f'{float(exponential_pd(lam, tau, config.snr_db)):12.3f}{len(hits):10d}')
    png = _plot(scans, sim, args, clutter_hits, tau)
    print(f'\nwrote {png}')
    return 0


def _plot(scans, sim: Simulator, args, clutter_hits, tau: float) -> Path:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    sonar = sim.sensor
    pose = sim.scene.platform_pose(0.0)[:3]
    xs, ys = sonar.cell_centres(pose)[..., 0], sonar.cell_centres(pose)[..., 1]
    canvas = PolarCanvas(xs.min() - 50, xs.max() + 50, ys.min() - 50, ys.max() + 50, 5.0)
    for _, amps, geom, _ in scans:
        canvas.paint(amps, geom, pose, hold_max=True)
    truth = np.array([(t['x'][0], t['y'][0]) for *_, t in scans if t is not None and len(t)])
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5))
    extent = (canvas.y_max, canvas.y_max - canvas.width * canvas.resolution,
              canvas.x_max - canvas.height * canvas.resolution, canvas.x_max)
    ax1.imshow(to_mono8(canvas.image, 25.0), cmap='gray', extent=extent, aspect='equal')
    if len(truth):
        ax1.plot(truth[:, 1], truth[:, 0], 'r-', lw=1, label='true track')
    for region in sim.scene.regions:
        poly = region.polygon
        ax1.fill(poly[:, 1], poly[:, 0], color='yellow', alpha=0.12, label=f'clutter lam {region.lam:g}')
    ax1.set_xlim(extent[0], extent[1])
    ax1.set_ylim(extent[2], extent[3])
    ax1.set_xlabel('y [m] (left)')
    ax1.set_ylabel('x [m] (forward)')
    ax1.set_title(f'{sim.config.scenario}: strongest echo of every cell over {len(scans)} scans')
    ax1.legend(loc='lower left')
    amps = np.concatenate([a.ravel() for _, a, _, _ in scans])
    s = np.linspace(0, 12, 300)
    ax2.hist(amps, bins=150, range=(0, 12), density=True, alpha=0.5, label='all cells')
    for lam in sorted(clutter_hits):
        ax2.plot(s, lam * np.exp(-lam * s), label=f'eq. 15, lam {lam:g}')
    ax2.axvline(tau, color='k', ls='--', label=f'tau {tau:g}')
    ax2.set_yscale('log')
    ax2.set_ylim(1e-5, 2)
    ax2.set_xlabel('echo amplitude s')
    ax2.set_ylabel('density')
    ax2.set_title('cell amplitudes against the exponential law')
    ax2.legend()
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    png = (args.out / f'demo_{sim.config.scenario}.png').resolve()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


if __name__ == '__main__':
    sys.exit(main())

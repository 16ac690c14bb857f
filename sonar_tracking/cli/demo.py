"""``make demo``: the harbour pipeline on the ESC paper's Scenario 2, through real ROS 2 nodes.

Runs ``sonar_stack --config config/stack_harbour.yaml --record out/demo_bag``: the simulated
harbour sonar (a target manoeuvring from clutter rate lam 1.6 into lam 0.8 at scan 50), the ESC
detector measuring the clutter density near the best track, and the IMM-IPDA tracker, each its own
process over DDS, the simulator at full speed, everything recorded. It then reads the bag back and
prints a summary (tracks confirmed, true and false by eqs. 47-48, RMSE, the threshold) and writes a
PNG of the tracks on the truth and the threshold and clutter density over time. With the view
extra installed (``requirements-view.txt``; ``make demo`` installs it) it first starts
``sonar_view`` and prints its address, so the run can be watched in a browser on this machine;
in a terminal the view stays open after the run until Enter is pressed (``--no-view``: none).
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from sonar_tracking import process

__all__ = ['main', 'read_run', 'summarise_run']

STACK = 'stack_harbour.yaml'


def read_run(bag: Path) -> dict:
    """Truth, tracks, threshold and density per scan from a recorded run (stamps in seconds)."""
    from rosbags.typesys import Stores, get_typestore

    import sonar_tracking.msgs as ma
    from sonar_tracking.io.bags import bag_topics, read_bag
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {t.name: t.msgtype for t in bag_topics(bag)}
    truth, tracks, thresholds, densities = {}, {}, [], []
    for m in read_bag(bag, ['/sonar/truth', '/tracks', '/detector/threshold', '/detector/clutter_density']):
        msg = store.deserialize_cdr(m.data, types[m.topic])
        if m.topic == '/sonar/truth':
            truth[ma.header_ns(msg)] = np.array(ma.cloud_to_array(msg))
        elif m.topic == '/tracks':
            tracks[ma.header_ns(msg)] = np.array(ma.cloud_to_array(msg))
        elif m.topic == '/detector/threshold':
            thresholds.append(msg.data)
        else:
            densities.append(msg.data)
    stamps = sorted(set(truth) & set(tracks))
    return {'stamps': [s / 1e9 for s in stamps], 'truth': [truth[s] for s in stamps],
            'tracks': [tracks[s] for s in stamps], 'threshold': thresholds, 'clutter_density': densities}


def summarise_run(run: dict) -> dict:
    """Eqs. 47-49 scan by scan; a confirmed track is true when most of its confirmed scans are CTT."""
    from sonar_tracking.core.detection import convert_measurements
    from sonar_tracking.core.tracking import TrackerConfig
    from sonar_tracking.core.tracking.management import initial_covariance
    from sonar_tracking.sim.presets import HARBOUR_SONAR_XY
    from sonar_tracking.studies.metrics import classify_tracks
    t0 = run['truth'][0][0]
    r0 = math.hypot(t0['x'] - HARBOUR_SONAR_XY[0], t0['y'] - HARBOUR_SONAR_XY[1])
    b0 = math.atan2(t0['y'] - HARBOUR_SONAR_XY[1], t0['x'] - HARBOUR_SONAR_XY[0])
    _, R0 = convert_measurements(np.array([r0]), np.array([b0]), 5.0, math.radians(0.1))
    P0 = initial_covariance(R0[0], TrackerConfig().init.speed_max)
    votes: dict[int, list[int]] = defaultdict(list)
    paths: dict[int, list] = defaultdict(list)
    has_ctt, errors = [], []
    for truth, tracks in zip(run['truth'], run['tracks']):
        conf = tracks[tracks['confirmed'] != 0]
        x = np.column_stack([truth[f] for f in ('x', 'y', 'vx', 'vy')])
        est = np.column_stack([conf[f] for f in ('x', 'y', 'vx', 'vy')]) if len(conf) else np.zeros((0, 4))
        cls = classify_tracks(x, est, P0)
        for rec, label in zip(conf, cls.label):
            votes[int(rec['track_id'])].append(int(label))
            paths[int(rec['track_id'])].append((float(rec['x']), float(rec['y'])))
        true_idx = np.flatnonzero(cls.label == 1)
        has_ctt.append(len(true_idx) > 0)
        if len(true_idx):
            errors.append(min(math.hypot(est[i, 0] - x[0, 0], est[i, 1] - x[0, 1]) for i in true_idx))
    true_ids = [i for i, v in votes.items() if v.count(1) > len(v) / 2]
    false_ids = [i for i in votes if i not in true_ids]
    return {'scans': len(run['stamps']), 'confirmed': len(votes), 'true': true_ids, 'false': false_ids,
            'cttr': float(np.mean(has_ctt)) if has_ctt else 0.0,
            'rmse': float(np.sqrt(np.mean(np.square(errors)))) if errors else math.nan,
            'threshold_final': run['threshold'][-1] if run['threshold'] else math.nan, 'paths': paths}


def main(argv: list[str] | None = None) -> int:
    """Entry point (``make demo`` runs ``python -m sonar_tracking.cli.demo``)."""
    parser = argparse.ArgumentParser(prog='sonar_demo', description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', type=Path, default=Path('out'))
    parser.add_argument('--timeout', type=float, default=110.0)
    parser.add_argument('--no-view', action='store_true', help='do not start the browser view (sonar_view)')
    args = parser.parse_args(argv)
    from sonar_tracking.resources import config_path
    bag = args.out / 'demo_bag'
    if bag.exists():
        shutil.rmtree(bag)
    args.out.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', '--config', str(config_path(STACK)),
           '--record', str(bag)]
    view = None if args.no_view else _start_view(args.out)
    try:
        code = _run_demo(args, cmd, bag)
    finally:
        if view is not None:
            _stop_view(view)
    return code


def _run_demo(args: argparse.Namespace, cmd: list[str], bag: Path) -> int:
    print(f'$ sonar_stack --config config/{STACK} --record {bag}', flush=True)
    t0 = time.monotonic()
    try:
        code = subprocess.run(cmd, timeout=args.timeout).returncode
    except subprocess.TimeoutExpired:
        print(f'error: the pipeline did not finish within {args.timeout:g} s', file=sys.stderr)
        return 1
    wall = time.monotonic() - t0
    if code != 0 or not (bag / 'metadata.yaml').exists():
        print(f'error: the pipeline failed (status {code})', file=sys.stderr)
        return 1
    run = read_run(bag)
    if not run['stamps']:
        print('error: the bag holds no scans with both truth and tracks', file=sys.stderr)
        return 1
    s = summarise_run(run)
    print()
    print(f'Scenario 2 through seaking_sim -> active_detector -> imm_ipda_tracker: {s["scans"]} scans in {wall:.1f} s')
    print(f'  confirmed tracks          {s["confirmed"]:>6d}')
    print(f'    true (eqs. 47-48)       {len(s["true"]):>6d}   ids {s["true"]}')
    print(f'    false                   {len(s["false"]):>6d}   ids {s["false"]}')
    print(f'  scans with a true track   {s["cttr"]:>9.0%}')
    print(f'  position RMSE (eq. 49)    {s["rmse"]:>8.2f} m')
    thresholds = run['threshold']
    print(f'  threshold: first {thresholds[0]:.2f}, scan 50 {thresholds[min(49, len(thresholds) - 1)]:.2f}, '
          f'final {s["threshold_final"]:.2f}')
    png = _plot(run, s, args.out / 'demo_harbour.png')
    print(f'\nbag: {bag}\nplot: {png.resolve()}')
    return 0


def _free_port(preferred: int) -> int:
    """``preferred`` if nothing listens there, else a free port the system picks."""
    for port in (preferred, 0):
        with socket.socket() as s:
            try:
                s.bind(('127.0.0.1', port))
            except OSError:
                continue
            return s.getsockname()[1]
    raise OSError('no free port')


def _start_view(out: Path) -> subprocess.Popen | None:
    """Start ``sonar_view`` (if its extra is installed) and print its address once it listens."""
    from sonar_tracking.cli.sonar_stack import _has_view
    if not _has_view():
        print('note: no live view (its extra is not installed: `make view` installs it)', flush=True)
        return None
    log = out / 'sonar_view.log'
    with log.open('w') as f:
        # --always: the whole run stays in the view, for a browser opened during or after it.
        proc = subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.sonar_view', '--always', '--grpc-port',
                                 str(_free_port(9876)), '--web-port', str(_free_port(9090))],
                                stdout=f, stderr=subprocess.STDOUT, start_new_session=True,
                                env=dict(os.environ, SONAR_TRACKING_DIE_WITH_PARENT='1'),
                                preexec_fn=process.child_dies_with_parent())
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline and proc.poll() is None:
        url = next((line.split(' ', 1)[1] for line in log.read_text().splitlines() if line.startswith('view: ')), None)
        if url:  # printed once its subscriptions exist, so the simulator waits for it too
            print(f'view: {url}\n      (open it in a browser on this machine to watch the run)', flush=True)
            return proc
        time.sleep(0.1)
    print(f'note: the live view did not start (see {log}); the demo runs without it', flush=True)
    _stop_view(proc, keep=False)
    return None


def _stop_view(proc: subprocess.Popen, keep: bool = True) -> None:
    """Stop the view; in a terminal, first keep it open until Enter so the run can be looked at."""
    if keep and proc.poll() is None and sys.stdin.isatty():
        try:
            input('\nThe view keeps the run: press Enter to close it. ')
        except (EOFError, KeyboardInterrupt):
            pass
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def _plot(run: dict, s: dict, path: Path) -> Path:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(14, 6.5))
    ax = fig.add_subplot(1, 2, 1)
    truth = np.array([(t['x'][0], t['y'][0]) for t in run['truth']])
    ax.plot(truth[:, 0], truth[:, 1], 'k-', lw=3, alpha=0.35, label='true track')
    y50 = truth[min(49, len(truth) - 1), 1]
    ax.axhspan(y50, truth[:, 1].max() + 300, color='gold', alpha=0.15, label='clutter lam 0.8 (else 1.6)')
    for tid, pts in s['paths'].items():
        p = np.array(pts)
        style = '-' if tid in s['true'] else ':'
        ax.plot(p[:, 0], p[:, 1], style, lw=1.5, label=f'T{tid} ({"true" if tid in s["true"] else "false"})')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_title('confirmed IMM-IPDA tracks on the truth (Scenario 2)')
    ax.legend(fontsize=8, loc='lower right')
    scans = np.arange(1, len(run['threshold']) + 1)
    ax2 = fig.add_subplot(2, 2, 2)
    ax2.plot(scans, run['threshold'], 'r-')
    ax2.axvline(50, color='gold', ls='--')
    ax2.set_ylabel('threshold')
    ax2.set_title('ESC threshold (density measured near the best track)')
    ax3 = fig.add_subplot(2, 2, 4, sharex=ax2)
    ax3.semilogy(scans[:len(run['clutter_density'])], np.maximum(run['clutter_density'], 1e-9), 'b-',
                 label='estimated')
    ax3.axhline(7.52e-5, color='k', ls='--', label='rho_D')
    ax3.axvline(50, color='gold', ls='--')
    ax3.set_xlabel('scan')
    ax3.set_ylabel('clutter density [1/m^2]')
    ax3.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


if __name__ == '__main__':
    sys.exit(main())

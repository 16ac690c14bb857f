"""``sonar_eval soak``: start, work, stop, many times: no node may crash or hang when it is stopped.

A cycle starts one node as its own process (``python -m sonar_tracking.nodes.NAME`` with the
parameter file it runs with in a stack or on a replayed recording), feeds it real input from this
process until it has published output, sends it SIGINT and waits for it to exit. In every other
cycle the input keeps coming, so the stop lands amid the node's work; in the others the input
ends first and the node has worked off what it had, as after a replay. The cycle passes when the
node exits with status 0 within ``--stop-timeout``; a crash is an exit by a signal (a negative
status: SIGSEGV, SIGABRT), a hang a node still running at the timeout (then killed).
``--cycles`` cycles per node, the nodes one after another, with one busy-looping process per CPU
beside them (``--load``, on by default), so that start-up, work and teardown interleave as on a
loaded vehicle computer. The nodes run with ``PYTHONFAULTHANDLER``: a crash prints the Python
stack of every thread, kept in the JSON (``--json``) with the exit status.

Inputs, published by this process in a DDS domain of its own
(:func:`~sonar_tracking.ros.runtime.private_domain`), and the output a cycle waits for:

=========================  ======================================================  ===============
node (parameter file)      input                                                   output
=========================  ======================================================  ===============
seaking_sim                none (harbour scans, ten a second, without end)         ``sonar/sector``
(sim_harbour)
active_detector            harbour sectors of ESC Scenario 1, 20 a second          ``detections``
imm_ipda_tracker           detections of a target in clutter, 20 a second          ``tracks``
fls_features               SeaKing sectors of FLS situation 9 with structure,      ``fls/regions``
(sensors/micron_seaking)   8-bit dB counts as a Micron or SeaKing sends them
gpf_tracker                FLS frames of imaging-sonar pings (image, info,         ``gpf/tracks``
(sensors/oculus_m750d)     regions), 15 a second
projected_sonar_adapter    imaging-sonar pings, 256 beams x 400 bins, 15 a second  ``sonar/sector``
=========================  ======================================================  ===============

How many outputs a cycle waits for before the SIGINT (2 to 4) comes from ``--seed``. Exit status:
0 when every cycle passed, 1 otherwise, 2 for bad arguments.
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ['NODES', 'Feed', 'Driver', 'add_arguments', 'main_args', 'make_feed', 'run_cycle', 'run_soak',
           'format_table']

NODES = ('seaking_sim', 'active_detector', 'imm_ipda_tracker', 'fls_features', 'gpf_tracker',
         'projected_sonar_adapter')

#: Parameter files of the nodes: the stacks' own, and for the FLS nodes the sensor presets a
#: recording is replayed with (a SeaKing's sectors, an Oculus-class imaging sonar's frames).
PARAMS_FILES = {'active_detector': 'active_detector.yaml', 'imm_ipda_tracker': 'imm_ipda.yaml',
                'fls_features': 'sensors/micron_seaking.yaml', 'gpf_tracker': 'sensors/oculus_m750d.yaml',
                'seaking_sim': 'sim_harbour.yaml'}
EXTRA_PARAMS = {'seaking_sim': ['rate:=10.0', 'duration:=0.0']}   # ten scans a second, without end

#: Characters of a failed cycle's stderr kept in the report.
STDERR_TAIL = 4000


def add_arguments(parser) -> None:
    """Arguments of ``sonar_eval soak``."""
    import argparse
    parser.add_argument('--cycles', type=int, default=50, help='start-work-stop cycles per node')
    parser.add_argument('--nodes', nargs='+', choices=NODES, default=list(NODES), metavar='NODE',
                        help=f'nodes to soak (default all: {" ".join(NODES)})')
    parser.add_argument('--load', action=argparse.BooleanOptionalAction, default=True,
                        help='run busy-looping processes beside the nodes (--load-processes of them)')
    parser.add_argument('--load-processes', type=int, default=None, metavar='N',
                        help='how many busy-looping processes --load runs (default one per CPU)')
    parser.add_argument('--seed', type=int, default=1, help='seed of the inputs and of the outputs waited for')
    parser.add_argument('--start-timeout', type=float, default=180.0,
                        help='seconds a node may take from its start to its outputs (the first start after an '
                        'install compiles kernels)')
    parser.add_argument('--stop-timeout', type=float, default=30.0, help='seconds a node may take to exit after SIGINT')
    parser.add_argument('--json', type=Path, default=None, help='write the results here')


def main_args(args) -> int:
    """Run the soak; print the table and write the JSON."""
    from sonar_tracking.cli._output import write_json
    if args.cycles < 1 or args.start_timeout <= 0 or args.stop_timeout <= 0 or (args.load_processes or 1) < 1:
        print('error: need --cycles >= 1, --load-processes >= 1 and positive timeouts', file=sys.stderr)
        return 2
    result = run_soak(list(dict.fromkeys(args.nodes)), args.cycles, load=args.load, seed=args.seed,
                      load_processes=args.load_processes,
                      start_timeout=args.start_timeout, stop_timeout=args.stop_timeout, progress=print)
    print(format_table(result))
    if args.json:
        write_json(args.json, result)
    return 0 if result['passed'] else 1


# -- inputs ------------------------------------------------------------------------------------
@dataclass
class Feed:
    """What one node is given and what it is watched for: ``output``, the topic and type counted;
    ``batches`` of ``(topic, message)`` published together, one batch per ``period`` seconds, in a
    loop, each batch stamped ``spacing_ns`` after the one before (so stamps only grow, as a node's
    time rule wants); ``types``, the message type of each input topic."""

    output: tuple[str, Any]
    batches: list[list[tuple[str, Any]]] = field(default_factory=list)
    period: float = 0.05
    spacing_ns: int = 50_000_000
    types: dict[str, Any] = field(default_factory=dict)


def _stamp(msg: Any, ns: int) -> None:
    import sonar_tracking.msgs as ma
    if hasattr(msg, 'map_load_time'):
        msg.map_load_time = ma.ns_to_stamp(ns)
    else:
        msg.header.stamp = ma.ns_to_stamp(ns)


def _sector_batches(scenario: str, sensor: str | None, n: int, seed: int) -> list[list[tuple[str, Any]]]:
    import sonar_tracking.msgs as ma
    from sonar_tracking.sim import SimConfig, Simulator
    config = SimConfig.for_scenario(scenario, sensor, duration=0.0) if sensor else \
        SimConfig.for_scenario(scenario, duration=0.0)
    sim = Simulator(config, np.random.default_rng(seed))
    out = []
    for _ in range(n):
        s = sim.next_sector()
        out.append([('sonar/sector', ma.array_to_image(s.amplitudes, frame_id='sonar')),
                    ('sonar/sector_info', ma.geometry_to_scan(s.geometry, amplitudes=s.amplitudes, frame_id='sonar'))])
    return out


def _detection_batches(n: int, seed: int) -> list[list[tuple[str, Any]]]:
    import sonar_tracking.msgs as ma
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        xy = np.concatenate([[[200.0 + 5.0 * k, 100.0 + 2.0 * k]] + rng.normal(0.0, 2.0, (1, 2)),
                             rng.uniform(-1000.0, 1000.0, (60, 2))])
        rec = np.zeros(len(xy), ma.DETECTION_DTYPE)
        rec['x'], rec['y'] = xy[:, 0], xy[:, 1]
        rec['range'], rec['bearing'] = np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0])
        rec['amplitude'] = 10.0
        rec['clutter_density'] = 1e-5
        rec['cov_xx'] = rec['cov_yy'] = 4.0
        out.append([('detections', ma.array_to_cloud(rec, frame_id='world'))])
    return out


def _frame_batches(n_pings: int, seed: int) -> list[list[tuple[str, Any]]]:
    """FLS frames as ``fls_features`` publishes them from an imaging sonar's pings (:func:`_ping_batches`
    through the live adapter's conversion and the front end with the ``oculus_m750d`` preset; its
    structure rejection off, so the moving targets stay regions)."""
    import sonar_tracking.msgs as ma
    from sonar_tracking.core.fls import FlsConfig, FlsProcessor
    from sonar_tracking.io import param_files
    from sonar_tracking.msgs.map_info import grid_to_map_info
    from sonar_tracking.nodes.projected_sonar_adapter import AdapterConfig, convert
    from sonar_tracking.resources import config_path
    preset = param_files.load(config_path(PARAMS_FILES['gpf_tracker']))
    flat = dict(next(values for name, values in param_files.sections(preset) if name == '/**/fls_features'))
    flat.pop('input_qos', None)
    fls = FlsProcessor(FlsConfig.from_flat({**flat, 'structure.enabled': False}))
    out = []
    for k, [(_, ping)] in enumerate(_ping_batches(n_pings, seed)):
        ping.header.stamp = ma.ns_to_stamp(1_000_000_000 + k * 66_000_000)
        image, scan, _ = convert(ping, AdapterConfig())
        amplitudes, geometry = ma.sector_from_messages(image, scan)
        for frame in fls.add_sector(amplitudes, geometry, (0.0, 0.0, 0.0), k * 0.066):
            out.append([('fls/image_info', grid_to_map_info(frame.grid, 0)),
                        ('fls/image', ma.array_to_image(frame.image, '32FC1', frame_id='world')),
                        ('fls/regions', ma.array_to_cloud(frame.regions, frame_id='world'))])
    return out


def _ping_batches(n: int, seed: int) -> list[list[tuple[str, Any]]]:
    """Imaging-sonar pings (``ProjectedSonarImage``: 256 beams over 130 deg, 400 bins of 5 cm, 8-bit
    speckle with three moving targets), as an Oculus-class driver publishes them."""
    import sonar_tracking.msgs as ma
    types = ma.rclpy_types()
    rng = np.random.default_rng(seed)
    n_beams, n_bins = 256, 400
    az = np.arcsin(np.linspace(-1.0, 1.0, n_beams) * math.sin(math.radians(65.0)))
    dirs = [types.new('geometry_msgs/msg/Vector3', x=0.0, y=-math.sin(a), z=math.cos(a)) for a in az]
    ranges = types.numeric_sequence(((np.arange(n_bins) + 0.5) * 0.05).astype(np.float32))
    out = []
    for k in range(n):
        values = np.clip(rng.rayleigh(20.0, (n_bins, n_beams)), 0, 255).astype(np.uint8)
        for row, col in ((100 + 2 * k, 60 + k), (200, 200 - k), (300 - 2 * k, 128)):
            values[row:row + 12, col:col + 8] = 250
        image = types.new('marine_acoustic_msgs/msg/SonarImageData', is_bigendian=False, dtype=0,
                          beam_count=n_beams, data=types.numeric_sequence(values.reshape(-1)))
        msg = types.new('marine_acoustic_msgs/msg/ProjectedSonarImage', header=ma.header(0, 'oculus', types),
                        beam_directions=dirs, ranges=ranges, image=image)
        out.append([('sonar_image', msg)])
    return out


def make_feed(node: str, seed: int) -> Feed:
    """The input and watched output of ``node`` (module docstring). Raises ImportError when a
    message package the node needs is missing."""
    from nav_msgs.msg import MapMetaData
    from sensor_msgs.msg import Image, LaserScan, PointCloud2
    sector_types = {'sonar/sector': Image, 'sonar/sector_info': LaserScan}
    if node == 'seaking_sim':
        return Feed(output=('sonar/sector', Image))
    if node == 'active_detector':
        return Feed(('detections', PointCloud2), _sector_batches('scenario1', None, 40, seed), 0.05, 1_000_000_000,
                    sector_types)
    if node == 'imm_ipda_tracker':
        return Feed(('tracks', PointCloud2), _detection_batches(100, seed), 0.05, 1_000_000_000,
                    {'detections': PointCloud2})
    if node == 'fls_features':
        return Feed(('fls/regions', PointCloud2), _sector_batches('fls9_structured', 'seaking675', 60, seed), 0.05,
                    500_000_000, sector_types)
    if node == 'gpf_tracker':
        return Feed(('gpf/tracks', PointCloud2), _frame_batches(30, seed), 1.0 / 15.0, 66_000_000,
                    {'fls/image_info': MapMetaData, 'fls/image': Image, 'fls/regions': PointCloud2})
    if node == 'projected_sonar_adapter':
        from marine_acoustic_msgs.msg import ProjectedSonarImage
        return Feed(('sonar/sector', Image), _ping_batches(30, seed), 1.0 / 15.0, 66_000_000,
                    {'sonar_image': ProjectedSonarImage})
    raise ValueError(f'unknown node {node!r}; known: {", ".join(NODES)}')


class Driver:
    """This process's ROS side: publishes a feed in a thread of its own, counts the watched output."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.node = rclpy.create_node('sonar_soak')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self._spin, daemon=True)
        self.spinner.start()
        self.count = 0
        self._stop = threading.Event()
        self._feeder: threading.Thread | None = None
        self._pubs: list = []
        self._sub = None

    def _spin(self) -> None:
        from rclpy.exceptions import InvalidHandle
        from rclpy.executors import ExternalShutdownException
        while True:
            try:
                self.executor.spin()
                return
            except ExternalShutdownException:
                return
            except InvalidHandle:
                continue   # a feed's entity was destroyed under the wait set: wait on the others

    def start(self, feed: Feed) -> None:
        """Publish ``feed``'s batches until :meth:`stop`; count its output."""
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.count = 0

        def heard(_msg: Any) -> None:
            self.count += 1
        self._sub = self.node.create_subscription(feed.output[1], feed.output[0], heard, qos)
        pubs = {topic: self.node.create_publisher(typ, topic, qos) for topic, typ in feed.types.items()}
        self._pubs = list(pubs.values())
        self._stop.clear()
        if feed.batches:
            self._feeder = threading.Thread(target=self._feed, args=(feed, pubs), daemon=True)
            self._feeder.start()

    def _feed(self, feed: Feed, pubs: dict) -> None:
        ns, k = time.time_ns(), 0
        while not self._stop.is_set():
            for topic, msg in feed.batches[k % len(feed.batches)]:
                _stamp(msg, ns)
                pubs[topic].publish(msg)
            ns += feed.spacing_ns
            k += 1
            self._stop.wait(feed.period)   # the pace of the input

    def pause(self) -> None:
        """End the feed; the output is still counted."""
        self._stop.set()
        if self._feeder is not None:
            self._feeder.join()
            self._feeder = None

    def stop(self) -> None:
        """End the feed; drop its publishers and subscription."""
        self.pause()
        for pub in self._pubs:
            self.node.destroy_publisher(pub)
        if self._sub is not None:
            self.node.destroy_subscription(self._sub)
        self._pubs, self._sub = [], None

    def close(self) -> None:
        """End the feed and the executor; destroy the node."""
        self.stop()
        self.executor.shutdown(timeout_sec=2.0)
        self.spinner.join(timeout=5.0)
        self.node.destroy_node()


# -- the cycles --------------------------------------------------------------------------------
def node_command(node: str) -> list[str]:
    """The command line of ``node`` in a cycle."""
    from sonar_tracking.resources import config_path
    cmd = [sys.executable, '-m', f'sonar_tracking.nodes.{node}', '--ros-args']
    if node in PARAMS_FILES:
        cmd += ['--params-file', str(config_path(PARAMS_FILES[node]))]
    for p in EXTRA_PARAMS.get(node, []):
        cmd += ['-p', p]
    return cmd


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


def _settled(driver: Driver, quiet: float, timeout: float) -> None:
    """Wait until the output count has not changed for ``quiet`` seconds (at most ``timeout``)."""
    deadline = time.monotonic() + timeout
    last, since = driver.count, time.monotonic()
    while time.monotonic() < deadline and time.monotonic() - since < quiet:
        time.sleep(0.02)
        if driver.count != last:
            last, since = driver.count, time.monotonic()


def run_cycle(driver: Driver, feed: Feed, node: str, need: int, start_timeout: float,
              stop_timeout: float, idle: bool = False) -> dict:
    """One start-work-stop cycle of ``node``: ``{'status', 'outcome', 'output_s', 'stop_s', 'stderr'}``
    (``outcome``: ``ok``, ``crash``, ``hang``, ``error`` for another status, ``no_output``). ``idle``:
    the input ends before the SIGINT and the node has worked off what it had (as after a replay),
    else the SIGINT lands amid the input."""
    from sonar_tracking import process
    env = dict(os.environ, PYTHONFAULTHANDLER='1', PYTHONUNBUFFERED='1')
    driver.start(feed)
    with tempfile.TemporaryFile(mode='w+') as err:
        t0 = time.monotonic()
        proc = subprocess.Popen(node_command(node), stdout=subprocess.DEVNULL, stderr=err, env=env,
                                start_new_session=True, preexec_fn=process.child_dies_with_parent())
        try:
            produced = _wait(lambda: driver.count >= need or proc.poll() is not None, start_timeout)
            output_s = time.monotonic() - t0
            produced = produced and proc.poll() is None
            if idle and produced and feed.batches:
                driver.pause()
                _settled(driver, 0.5, stop_timeout)
            t1 = time.monotonic()
            if proc.poll() is None:
                os.kill(proc.pid, signal.SIGINT)
            try:
                status: int | None = proc.wait(stop_timeout)
            except subprocess.TimeoutExpired:
                status = None
            stop_s = time.monotonic() - t1
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            driver.stop()
        err.seek(0)
        text = err.read()
    if status is None:
        outcome = 'hang'
    elif status < 0:
        outcome = 'crash'
    elif status != 0:
        outcome = 'error'
    elif not produced:
        outcome = 'no_output'
    else:
        outcome = 'ok'
    return {'status': status, 'outcome': outcome, 'output_s': output_s, 'stop_s': stop_s,
            'stderr': '' if outcome == 'ok' else text[-STDERR_TAIL:]}


def start_load(n: int | None = None) -> list[subprocess.Popen]:
    """``n`` (default one per CPU) busy-looping processes that end with this one."""
    from sonar_tracking import process
    return [subprocess.Popen([sys.executable, '-c', 'while True: pass'], stdin=subprocess.DEVNULL,
                             preexec_fn=process.child_dies_with_parent(signal.SIGKILL))
            for _ in range(n or os.cpu_count() or 1)]


def run_soak(nodes: list[str], cycles: int, *, load: bool = True, seed: int = 1, start_timeout: float = 180.0,
             stop_timeout: float = 30.0, progress: Callable[[str], None] = lambda text: None,
             load_processes: int | None = None) -> dict:
    """``cycles`` start-work-stop cycles of each of ``nodes``, with ``load_processes`` busy loops beside
    them when ``load`` (default one per CPU); the result (``passed`` when every cycle did, per node
    the counts of each outcome, exit statuses, times and failed cycles)."""
    from sonar_tracking.ros.runtime import configure_dds, private_domain, start_ros
    configure_dds()
    domain = private_domain()   # before ROS starts: the nodes of the soak and this process see only each other
    import rclpy
    rng = np.random.default_rng(seed)
    t0 = time.monotonic()
    start_ros([])   # without rclpy's signal thread: Ctrl-C is a KeyboardInterrupt here, and the cleanup runs
    driver = Driver()
    hogs = start_load(load_processes) if load else []
    result: dict[str, Any] = {'cycles': cycles, 'load_processes': len(hogs), 'seed': seed, 'domain': domain,
                              'nodes': {}, 'skipped': {}}
    try:
        for node in nodes:
            try:
                feed = make_feed(node, seed)
            except ImportError as exc:
                result['skipped'][node] = f'{type(exc).__name__}: {exc}'
                progress(f'{node}: skipped ({exc})')
                continue
            started = time.monotonic()
            runs = []
            for k in range(cycles):
                run = run_cycle(driver, feed, node, int(rng.integers(2, 5)), start_timeout, stop_timeout,
                                idle=bool(k % 2))
                runs.append(run)
                if run['outcome'] != 'ok':
                    progress(f'{node} cycle {k + 1}/{cycles}: {run["outcome"]} (status {run["status"]})\n'
                             + run['stderr'][-1500:])
            result['nodes'][node] = _summary(runs, time.monotonic() - started)
            progress(f'{node}: {cycles} cycles, {result["nodes"][node]["failures"]} failed, '
                     f'{result["nodes"][node]["wall_s"]:.0f} s')
    finally:
        driver.close()
        rclpy.try_shutdown()
        for hog in hogs:
            hog.kill()
            hog.wait()
    result['wall_s'] = time.monotonic() - t0
    result['passed'] = all(s['failures'] == 0 for s in result['nodes'].values())
    return result


def _summary(runs: list[dict], wall_s: float) -> dict:
    outcomes = Counter(r['outcome'] for r in runs)
    statuses = Counter('hang' if r['status'] is None else str(r['status']) for r in runs)
    return {'cycles': len(runs), 'crashes': outcomes['crash'], 'hangs': outcomes['hang'],
            'errors': outcomes['error'], 'no_output': outcomes['no_output'],
            'failures': len(runs) - outcomes['ok'], 'exit_statuses': dict(sorted(statuses.items())),
            'output_s_median': float(np.median([r['output_s'] for r in runs])),
            'stop_s_median': float(np.median([r['stop_s'] for r in runs])),
            'stop_s_max': float(max(r['stop_s'] for r in runs)), 'wall_s': wall_s,
            'failed': [{'cycle': k + 1, **{key: r[key] for key in ('outcome', 'status', 'stderr')}}
                       for k, r in enumerate(runs) if r['outcome'] != 'ok']}


def format_table(result: dict) -> str:
    """The per-node table of a soak result."""
    lines = [f'{"node":25s} {"cycles":>6s} {"crashes":>7s} {"hangs":>5s} {"other":>5s}  {"stop s (med/max)":>16s} '
             f'{"wall s":>7s}  exit statuses']
    for node, s in result['nodes'].items():
        lines.append(f'{node:25s} {s["cycles"]:6d} {s["crashes"]:7d} {s["hangs"]:5d} '
                     f'{s["errors"] + s["no_output"]:5d}  {s["stop_s_median"]:7.2f}/{s["stop_s_max"]:<8.2f} '
                     f'{s["wall_s"]:7.0f}  ' + ', '.join(f'{k}: {v}' for k, v in s['exit_statuses'].items()))
    for node, why in result['skipped'].items():
        lines.append(f'{node:25s} skipped: {why}')
    lines.append(f'{result["load_processes"]} load processes; {result["wall_s"]:.0f} s in all; '
                 + ('every cycle passed' if result['passed'] else 'FAILED'))
    return '\n'.join(lines)

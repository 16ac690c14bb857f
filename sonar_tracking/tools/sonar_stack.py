"""``sonar_stack``: run a whole pipeline as child processes from one YAML file (no launch files).

The file names the nodes to start, each with an executable of this package, an optional
parameter file (relative to the YAML file, or in the package's ``config/``), single parameters
and remappings; and what to do when a node exits: ``stop`` the stack (the default; the stack's
exit status is 0 if that node exited cleanly, 1 otherwise), ``restart`` it (up to
``max_restarts`` times) or ``ignore`` it::

    on_exit: stop            # default for every node
    max_restarts: 3
    nodes:
      seaking_sim:
        executable: seaking_sim
        params_file: sim_harbour.yaml
        parameters: {rate: 1.0}
        remappings: {/sonar/fan: /harbour/fan}
        on_exit: stop
        wait_for: {/sonar/sector: 1, /detections: 1}   # start once these have that many subscribers
      active_detector:
        params_file: active_detector.yaml     # executable defaults to the node's key
    record:
      topics: [/sonar/sector, /sonar/sector_info, /detections, /tracks]

Nodes start in file order; one with ``wait_for`` starts only once each named topic has at least
that many subscribers (so a simulator running at full speed starts after the pipeline listens).
Every child's output is printed line by line prefixed with its name. Ctrl-C or SIGTERM sends
SIGINT to every child and waits up to 5 s in all before killing what is left; children also get
SIGTERM from the kernel if the stack itself dies (Linux ``PR_SET_PDEATHSIG``), so none is left
behind. ``--record DIR`` also runs ``bag_record`` on the ``record`` topics (all topics if none),
started first; nodes with ``wait_for`` then also wait for the recorder to listen. ``--view``
likewise starts ``sonar_view`` first (``--view "ARGS"`` passes it options) and waits for it.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import yaml

__all__ = ['main', 'StackConfig', 'NodeSpec', 'load_stack']

_ON_EXIT = ('stop', 'restart', 'ignore')


class StackError(ValueError):
    """The stack file is malformed; the message says where."""


@dataclass
class NodeSpec:
    """One child: name, executable, parameters file, parameters, remappings, exit policy."""

    name: str
    executable: str
    params_file: Path | None = None
    parameters: dict = field(default_factory=dict)
    remappings: dict = field(default_factory=dict)
    on_exit: str = 'stop'
    extra_args: list = field(default_factory=list)
    wait_for: dict = field(default_factory=dict)


@dataclass
class StackConfig:
    """The nodes, the restart limit, the topics ``--record`` records, and how long the others may
    finish their queued work after a node exits and stops the stack."""

    nodes: list[NodeSpec]
    max_restarts: int = 3
    record_topics: list[str] = field(default_factory=list)
    stop_delay: float = 1.0


def _entry_points() -> dict[str, str]:
    """Console script name -> module of this package."""
    eps = metadata.entry_points(group='console_scripts')
    return {ep.name: ep.value.split(':')[0] for ep in eps if ep.value.startswith('sonar_tracking.')}


def _resolve(path: str, base: Path) -> Path:
    p = Path(path)
    if p.is_absolute():
        return p
    if (base / p).exists():
        return base / p
    from sonar_tracking.resources import config_path
    try:
        return config_path(str(p))
    except FileNotFoundError:
        raise StackError(f'parameter file {path} not found next to the stack file nor in the package config') from None


def load_stack(path: Path) -> StackConfig:
    """Read and check a stack file."""
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise StackError(f'cannot read {path}: {exc}') from None
    if not isinstance(data, dict) or not isinstance(data.get('nodes'), dict) or not data['nodes']:
        raise StackError(f'{path}: needs a "nodes:" mapping with at least one node')
    default_exit = data.get('on_exit', 'stop')
    scripts = _entry_points()
    nodes = []
    for name, spec in data['nodes'].items():
        spec = spec or {}
        if not isinstance(spec, dict):
            raise StackError(f'{path}: node {name} must be a mapping')
        unknown = set(spec) - {'executable', 'params_file', 'parameters', 'remappings', 'on_exit', 'args', 'wait_for'}
        if unknown:
            raise StackError(f'{path}: node {name} has unknown keys {sorted(unknown)}')
        exe = spec.get('executable', name)
        if exe not in scripts:
            raise StackError(f'{path}: node {name}: unknown executable {exe!r}; known: {sorted(scripts)}')
        on_exit = spec.get('on_exit', default_exit)
        if on_exit not in _ON_EXIT:
            raise StackError(f'{path}: node {name}: on_exit must be one of {list(_ON_EXIT)}, not {on_exit!r}')
        wait_for = spec.get('wait_for') or {}
        if not isinstance(wait_for, dict) or not all(isinstance(v, int) and v >= 0 for v in wait_for.values()):
            raise StackError(f'{path}: node {name}: wait_for must map topics to subscriber counts')
        nodes.append(NodeSpec(name=name, executable=exe,
                              params_file=_resolve(spec['params_file'], path.parent) if spec.get('params_file') else None,
                              parameters=dict(spec.get('parameters') or {}),
                              remappings=dict(spec.get('remappings') or {}), on_exit=on_exit,
                              extra_args=[str(a) for a in spec.get('args') or []], wait_for=dict(wait_for)))
    record = data.get('record') or {}
    return StackConfig(nodes=nodes, max_restarts=int(data.get('max_restarts', 3)),
                       record_topics=list(record.get('topics') or []), stop_delay=float(data.get('stop_delay', 1.0)))


def command(spec: NodeSpec) -> list[str]:
    """The child's command line: ``python -m <module> [args] --ros-args ...``."""
    module = _entry_points()[spec.executable]
    cmd = [sys.executable, '-m', module, *spec.extra_args, '--ros-args']
    if spec.params_file:
        cmd += ['--params-file', str(spec.params_file)]
    for key, value in spec.parameters.items():
        cmd += ['-p', f'{key}:={json.dumps(value)}']
    for src, dst in spec.remappings.items():
        cmd += ['-r', f'{src}:={dst}']
    return cmd


class Child:
    """A running node with its output relay."""

    def __init__(self, spec: NodeSpec, out_lock: threading.Lock) -> None:
        self.spec = spec
        self.restarts = 0
        self.out_lock = out_lock
        self.proc: subprocess.Popen | None = None
        self.start()

    def start(self) -> None:
        env = dict(os.environ, SONAR_TRACKING_DIE_WITH_PARENT='1', PYTHONUNBUFFERED='1')
        self.proc = subprocess.Popen(command(self.spec), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1, start_new_session=True, env=env)
        threading.Thread(target=self._relay, args=(self.proc,), daemon=True).start()

    def _relay(self, proc: subprocess.Popen) -> None:
        for line in proc.stdout:
            with self.out_lock:
                sys.stdout.write(f'[{self.spec.name}] {line}')
                sys.stdout.flush()

    def signal(self, signum: int) -> None:
        if self.proc and self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signum)
            except ProcessLookupError:
                pass


class _GraphProbe:
    """A small rclpy node of the stack's own, to count subscribers for ``wait_for``."""

    def __init__(self) -> None:
        from sonar_tracking.ros.runtime import configure_dds
        configure_dds()
        import rclpy
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions
        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('sonar_stack', context=self.context)

    def ready(self, wait_for: dict) -> bool:
        return all(self.node.count_subscribers(topic) >= n for topic, n in wait_for.items())

    def close(self) -> None:
        self.node.destroy_node()
        self.context.try_shutdown()


def run(config: StackConfig, record_dir: Path | None = None, grace: float = 5.0, view: str | None = None) -> int:
    """Start the children, watch them, stop them; returns the stack's exit status."""
    lock = threading.Lock()
    stop = threading.Event()

    def say(text: str) -> None:
        with lock:
            print(f'[sonar_stack] {text}', flush=True)

    signal.signal(signal.SIGINT, lambda *a: stop.set())
    signal.signal(signal.SIGTERM, lambda *a: stop.set())
    specs = list(config.nodes)
    if record_dir is not None:
        # The recorder starts first, and nodes that wait for listeners also wait for it.
        recorder = NodeSpec(name='bag_record', executable='bag_record', on_exit='stop',
                            extra_args=['-o', str(record_dir), *config.record_topics])
        for spec in specs:
            if spec.wait_for:
                for topic in config.record_topics:
                    spec.wait_for[topic] = spec.wait_for.get(topic, 0) + 1
        specs.insert(0, recorder)
    if view is not None:  # the view listens to every pipeline topic: waited topics get one more listener
        specs.insert(0, NodeSpec(name='sonar_view', executable='sonar_view', on_exit='ignore', extra_args=shlex.split(view)))
        for spec in specs:
            spec.wait_for = {topic: n + 1 for topic, n in spec.wait_for.items()}
    children = []
    graph = _GraphProbe() if any(s.wait_for for s in specs) else None
    try:
        for spec in specs:
            if spec.wait_for:
                say(f'{spec.name} waits for subscribers: ' + ', '.join(f'{t} >= {n}' for t, n in spec.wait_for.items()))
                while not stop.is_set() and not graph.ready(spec.wait_for):
                    time.sleep(0.05)
                if stop.is_set():
                    break
            children.append(Child(spec, lock))
            say(f'started {spec.name} (pid {children[-1].proc.pid})')
    finally:
        if graph is not None:
            graph.close()
    status = 0
    gone: set[str] = set()
    while not stop.is_set():
        time.sleep(0.1)
        for child in children:
            code = child.proc.poll()
            name = child.spec.name
            if code is None or name in gone:
                continue
            if child.spec.on_exit == 'restart' and child.restarts < config.max_restarts:
                child.restarts += 1
                say(f'{name} exited with status {code}: restarting ({child.restarts}/{config.max_restarts})')
                time.sleep(0.5)
                child.start()
            elif child.spec.on_exit == 'ignore':
                say(f'{name} exited with status {code}; the others keep running')
                gone.add(name)
            else:
                say(f'{name} exited with status {code}: stopping the stack')
                status = 0 if code == 0 else 1
                if code == 0:
                    stop.wait(config.stop_delay)  # let the others finish what is queued
                stop.set()
                break
    say('stopping')
    for child in children:
        child.signal(signal.SIGINT)
    deadline = time.monotonic() + grace
    for child in children:
        try:
            child.proc.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            say(f'{child.spec.name} did not stop within {grace:g} s: killed')
            child.signal(signal.SIGKILL)
            child.proc.wait()
    return status


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``sonar_stack``."""
    parser = argparse.ArgumentParser(prog='sonar_stack', description=__doc__.split('\n\n')[0])
    parser.add_argument('--config', type=Path, required=True, help='stack YAML file (see config/stack_*.yaml)')
    parser.add_argument('--record', type=Path, default=None, metavar='DIR', help='also record a bag into DIR')
    parser.add_argument('--view', nargs='?', const='', default=None, metavar='ARGS',
                        help='also run sonar_view, the browser view (ARGS: its options, quoted)')
    args = parser.parse_args(argv)
    try:
        config = load_stack(args.config)
    except StackError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if args.record is not None and args.record.exists():
        print(f'error: {args.record} exists already', file=sys.stderr)
        return 2
    if args.view is not None and not _has_view():
        from sonar_tracking.tools.sonar_view import MISSING
        print(f'error: {MISSING}', file=sys.stderr)
        return 2
    return run(config, args.record, view=args.view)


def _has_view() -> bool:
    import importlib.util
    try:
        return importlib.util.find_spec('rerun') is not None
    except (ImportError, ValueError):
        return False


if __name__ == '__main__':
    sys.exit(main())

"""``sonar_stack``: run a whole pipeline as child processes from one YAML file (no launch files).

The file names the nodes to start, each with an executable of this package, an optional
parameter file (absolute, relative to the YAML file, or ``package:NAME`` for a file of the package's
``config/``; a relative file missing beside the stack is an error, not the package's file of that
name; the stack says which file each node reads), single parameters
and remappings; and what to do when a node exits: ``stop`` the stack (the default; the stack's
exit status is 0 if that node exited cleanly, 1 otherwise), ``restart`` it (up to
``max_restarts`` times) or ``ignore`` it::

    on_exit: stop            # default for every node
    max_restarts: 3
    namespace: harbour       # optional: the whole stack in /harbour
    nodes:
      seaking_sim:
        executable: seaking_sim
        params_file: package:sim_harbour.yaml   # a file of the package's config/
        parameters: {rate: 1.0}
        remappings: {sonar/fan: fan}
        on_exit: stop
        wait_for: {sonar/sector: 1, detections: 1}   # start once these have that many subscribers
      active_detector:
        params_file: detector.yaml            # beside this file; executable defaults to the node's key
        namespace: left                       # optional: this node in /harbour/left
    record:
      topics: [sonar/sector, sonar/sector_info, detections, tracks]

Nodes start in file order; one with ``wait_for`` starts only once each named topic has at least
that many subscribers (so a simulator running at full speed starts after the pipeline listens).
Every child's output is printed line by line prefixed with its name. Ctrl-C or SIGTERM sends
SIGINT to every child and waits up to 5 s in all before killing what is left; children also get
SIGTERM from the kernel if the stack itself dies (Linux ``PR_SET_PDEATHSIG``), so none is left
behind. ``--record DIR`` also runs ``bag_record`` on the ``record`` topics (all topics if none),
started first; nodes with ``wait_for`` then also wait for the recorder to listen. ``--view``
likewise starts ``sonar_view`` first, in the stack's namespace (``--view "ARGS"`` passes it options),
logging every record message of the whole run (``--always --qos reliable``), and runs a simulator
that the stack file runs at full speed in real time (``rate`` 1) instead, unless ``--set`` gives its
rate; a node's ``view_parameters`` (``{rate: 0.25}``) replace its parameters under ``--view`` alone,
where ``--set`` does not give them, and the file's ``view_args`` (``--fan-period 2``) come before
``--view``'s own; when the pipeline ends
by itself, the stack stops its nodes but keeps the view serving the run to a browser until Ctrl-C
or SIGTERM (which during the run stop the view with the rest).

Namespaces: ``namespace:`` at the top of the file puts the whole stack there, and a node's own
``namespace:`` puts that node there (a relative one under the stack's, an absolute one as it is).
``--namespace NS`` (or ``--ros-args -r __ns:=NS``, as with ``ros2 run``) moves everything, file
namespaces included, under ``NS``; so two stacks run side by side in ``/a`` and ``/b``. Relative
names in ``wait_for`` resolve in the node's namespace and relative ``record`` topics in the stack's,
as ROS resolves the nodes' own relative topic names; absolute names stay. Parameter files key
their sections ``/**/NODE_NAME:`` so that they apply in any namespace, as the package's files do; a
namespaced node whose file keys its section by the bare name (which ROS applies in the root
namespace only) is refused before anything starts.

A stack is named by a file (``--config path/to/stack.yaml``) or by a name looked up in the
package's ``config/`` wherever the package is installed (``sonar_stack harbour`` finds
``stack_harbour.yaml``; ``sonar_stack --list`` shows them). ``--set NODE.PARAM=VALUE`` (repeatable)
sets a parameter of one node of the stack over its file and parameters, the value read as YAML
(``--set seaking_sim.duration=30``, ``--set active_detector.esc.enabled=false``); a number in
exponent form without a decimal point (``1e-5``) is a number, not the string YAML 1.1 makes it.
``--dry-run`` prints the children's command lines and exits.

Sensor presets: ``--preset NAME`` gives every node whose parameter file is a sensor preset (a file
of the package's ``config/sensors/``) the preset ``NAME`` instead (``config/sensors/NAME.yaml``, or
a path to your own preset file): ``sonar_stack recording --preset aris_didson``.

Readiness: the package's processing nodes say on ``~/status`` whether they take input yet
(``starting``, ``learning``, ``ready``: :mod:`sonar_tracking.ros.status`), and the stack publishes
the least ready state of its nodes, with each node's, on ``sonar_stack/status`` in its namespace
(the same latched record). A node with ``wait_ready: true`` starts only once no node of the stack
says ``starting`` (besides its ``wait_for``). ``--replay "BAG [bag_replay options]"`` replays a
recording into the stack so: ``bag_replay`` starts once every node takes input (and the recorder
listens, with ``--record``), waits for ``/sonar/sector`` and ``/sonar/sector_info`` to be matched,
and the stack stops when the replay ends (``sonar_stack recording_active --replay rec_sectors
--record out/run``). The bag's topics are absolute, so ``--replay`` runs in the root namespace only.
"""
from __future__ import annotations

import argparse
import json
import os
import re
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

from sonar_tracking import process

__all__ = ['main', 'StackConfig', 'NodeSpec', 'StackError', 'load_stack', 'find_stack', 'shipped_stacks',
           'apply_settings', 'move', 'command', 'resolve_name', 'check_params_files', 'PACKAGE_PREFIX',
           'apply_preset', 'sensor_presets', 'add_replay', 'node_name', 'STATUS_EXECUTABLES', 'REPLAY_WAIT']

_ON_EXIT = ('stop', 'restart', 'ignore')

#: The executables whose nodes publish their state on ``~/status`` (the package's processing nodes,
#: :class:`~sonar_tracking.ros.node.SonarNode`); their node names are the executables' names.
STATUS_EXECUTABLES = frozenset({'active_detector', 'imm_ipda_tracker', 'fls_features', 'gpf_tracker',
                                'projected_sonar_adapter'})
#: Topics a ``--replay`` waits to be matched with the stack's readers (a recording's input).
REPLAY_WAIT = ('/sonar/sector', '/sonar/sector_info')


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
    namespace: str = '/'
    wait_ready: bool = False
    view_parameters: dict = field(default_factory=dict)


@dataclass
class StackConfig:
    """The nodes, the restart limit, the topics ``--record`` records, and how long the others may
    finish their queued work after a node exits and stops the stack."""

    nodes: list[NodeSpec]
    max_restarts: int = 3
    record_topics: list[str] = field(default_factory=list)
    stop_delay: float = 1.0
    namespace: str = '/'
    view_args: list[str] = field(default_factory=list)


def _entry_points() -> dict[str, str]:
    """Console script name -> module of this package."""
    eps = metadata.entry_points(group='console_scripts')
    return {ep.name: ep.value.split(':')[0] for ep in eps if ep.value.startswith('sonar_tracking.')}


#: ``params_file: package:NAME`` names a file of the package's ``config/`` (wherever it is installed).
PACKAGE_PREFIX = 'package:'


def _resolve(path: str, base: Path) -> Path:
    """A node's parameter file: absolute, relative to the stack file's folder, or ``package:NAME``. A
    relative file that is not beside the stack is an error, never the package's file of the same name
    (a copied stack must not run the package's preset without saying so)."""
    if path.startswith(PACKAGE_PREFIX):
        from sonar_tracking.resources import config_path
        name = path[len(PACKAGE_PREFIX):]
        try:
            return config_path(name)
        except FileNotFoundError:
            raise StackError(f'parameter file {path}: the package config has no {name}') from None
    p = Path(path)
    found = p if p.is_absolute() else base / p
    if found.is_file():
        return found
    hint = ''
    if not p.is_absolute():
        from sonar_tracking.resources import config_path
        try:
            hint = (f"; the package has one of that name ({config_path(path)}): write 'params_file: "
                    f"{PACKAGE_PREFIX}{path}' to use it")
        except FileNotFoundError:
            pass
    raise StackError(f'parameter file {found} not found' + hint)


_NAME_TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
_STACK_KEYS = {'nodes', 'on_exit', 'max_restarts', 'stop_delay', 'record', 'namespace', 'view_args'}
_NODE_KEYS = {'executable', 'params_file', 'parameters', 'remappings', 'on_exit', 'args', 'wait_for', 'namespace',
              'wait_ready', 'view_parameters'}


def _namespace(text, where: str) -> str:
    """A namespace as given (``a``, ``/a/b``, ``/``), checked; relative ones keep no leading slash."""
    if not isinstance(text, str):
        raise StackError(f'{where}: a namespace must be a string, not {text!r}')
    tokens = [t for t in text.strip('/').split('/')] if text.strip('/') else []
    if '//' in text or any(not _NAME_TOKEN.fullmatch(t) for t in tokens):
        raise StackError(f'{where}: {text!r} is not a ROS namespace (names of letters, digits and _, '
                         'not starting with a digit, separated by /)')
    return ('/' if text.startswith('/') else '') + '/'.join(tokens)


def _join(outer: str, inner: str) -> str:
    """``inner`` inside ``outer`` (an absolute ``inner`` stays as it is); the result is absolute."""
    if inner.startswith('/'):
        return inner
    parts = [p for p in (outer.strip('/'), inner.strip('/')) if p]
    return '/' + '/'.join(parts)


def resolve_name(name: str, namespace: str) -> str:
    """A topic name as ROS resolves it in ``namespace``: relative names go inside, absolute ones stay."""
    return name if name.startswith('/') else _join(namespace, name)


def _number(value):
    """YAML 1.1 reads ``1e-5`` as a string; a parameter value that spells a number is the number."""
    if isinstance(value, str) and re.fullmatch(r'[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+', value.strip()):
        return float(value)
    if isinstance(value, list):
        return [_number(v) for v in value]
    return value


def load_stack(path: Path) -> StackConfig:
    """Read and check a stack file; node namespaces come out absolute (the stack's joined with the node's)."""
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise StackError(f'cannot read {path}: {exc}') from None
    if not isinstance(data, dict) or not isinstance(data.get('nodes'), dict) or not data['nodes']:
        raise StackError(f'{path}: needs a "nodes:" mapping with at least one node')
    unknown = set(data) - _STACK_KEYS
    if unknown:
        raise StackError(f'{path}: unknown keys {sorted(unknown)}; known: {sorted(_STACK_KEYS)}')
    stack_ns = _join('/', _namespace(data.get('namespace', '/'), f'{path}: namespace'))
    default_exit = data.get('on_exit', 'stop')
    scripts = _entry_points()
    nodes = []
    for name, spec in data['nodes'].items():
        spec = spec or {}
        if not isinstance(spec, dict):
            raise StackError(f'{path}: node {name} must be a mapping')
        unknown = set(spec) - _NODE_KEYS
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
        wait_ready = spec.get('wait_ready', False)
        if not isinstance(wait_ready, bool):
            raise StackError(f'{path}: node {name}: wait_ready must be true or false, not {wait_ready!r}')
        view_parameters = spec.get('view_parameters') or {}
        if not isinstance(view_parameters, dict):
            raise StackError(f'{path}: node {name}: view_parameters must map parameter names to values')
        nodes.append(NodeSpec(name=name, executable=exe,
                              params_file=(_resolve(spec['params_file'], path.parent) if spec.get('params_file')
                                           else None),
                              parameters={k: _number(v) for k, v in (spec.get('parameters') or {}).items()},
                              remappings=dict(spec.get('remappings') or {}), on_exit=on_exit,
                              extra_args=[str(a) for a in spec.get('args') or []], wait_for=dict(wait_for),
                              namespace=_join(stack_ns, _namespace(spec.get('namespace', ''),
                                                                   f'{path}: node {name}: namespace')),
                              wait_ready=wait_ready,
                              view_parameters={k: _number(v) for k, v in view_parameters.items()}))
    record = data.get('record') or {}
    return StackConfig(nodes=nodes, max_restarts=int(data.get('max_restarts', 3)),
                       record_topics=list(record.get('topics') or []), stop_delay=float(data.get('stop_delay', 1.0)),
                       namespace=stack_ns, view_args=_view_args(data.get('view_args'), path))


def shipped_stacks() -> list[Path]:
    """The stack files in the package's ``config/`` directories (first of each name)."""
    from sonar_tracking.resources import config_dirs
    found: dict[str, Path] = {}
    for d in config_dirs():
        for p in sorted(d.glob('stack_*.yaml')) if d.is_dir() else ():
            found.setdefault(p.name, p)
    return sorted(found.values(), key=lambda p: p.name)


def find_stack(name: str) -> Path:
    """A stack file: an existing path, else ``name``, ``name.yaml``, ``stack_name.yaml`` in the package config."""
    p = Path(name)
    if p.is_file():
        return p
    from sonar_tracking.resources import config_path
    if p.name == name:
        stem = name[:-5] if name.endswith('.yaml') else name
        for candidate in (f'{stem}.yaml', f'stack_{stem}.yaml'):
            try:
                return config_path(candidate)
            except FileNotFoundError:
                pass
    known = ', '.join(q.name for q in shipped_stacks()) or 'none'
    raise StackError(f'no stack file {name!r}: not a file, nor in the package config (shipped stacks: {known})')


def apply_settings(config: StackConfig, settings: list[str]) -> None:
    """Apply ``NODE.PARAM=VALUE`` settings (value read as YAML) over the nodes' parameters."""
    nodes = {spec.name: spec for spec in config.nodes}
    for text in settings:
        key, sep, value = text.partition('=')
        node, dot, param = key.strip().partition('.')
        if not sep or not dot or not param:
            raise StackError(f'--set {text!r}: expected NODE.PARAM=VALUE, e.g. seaking_sim.duration=30')
        if node not in nodes:
            raise StackError(f'--set {text!r}: no node {node!r} in the stack; nodes: {", ".join(nodes)}')
        try:
            parsed = yaml.safe_load(value) if value.strip() else ''
        except yaml.YAMLError as exc:
            raise StackError(f'--set {text!r}: the value is not YAML: {exc}') from None
        nodes[node].parameters[param] = _number(parsed)


def view_spec(config: StackConfig, view: str) -> NodeSpec:
    """``--view ARGS``'s ``sonar_view``: every record message of the whole run (reliable, keep-last:
    never blocks a writer), then the stack file's ``view_args``, then ``ARGS`` (the last of an option
    counts)."""
    return NodeSpec(name='sonar_view', executable='sonar_view', on_exit='ignore',
                    extra_args=['--always', '--qos', 'reliable', *config.view_args, *shlex.split(view)],
                    namespace=config.namespace)


def _view_args(value, path) -> list[str]:
    """A stack file's ``view_args``: sonar_view's options under ``--view`` (a list, or one string split
    as a shell would)."""
    if value is None:
        return []
    if isinstance(value, str):
        return shlex.split(value)
    if isinstance(value, list):
        return [str(v) for v in value]
    raise StackError(f'{path}: view_args must be a list of sonar_view options or a string, not {value!r}')


def apply_view_settings(config: StackConfig, settings: list[str]) -> list[tuple[str, float]]:
    """``--view``: a node's ``view_parameters`` replace its parameters, and a simulator of the stack
    (``seaking_sim``) that its file runs at full speed (``rate`` 0) runs in real time (``rate`` 1)
    instead, so that a browser keeps up with the run; what ``settings`` (``--set``) give stays. Returns
    the simulators whose rate changed, with the rate."""
    given = {text.partition('=')[0].strip() for text in settings}
    changed = []
    for spec in config.nodes:
        view = dict(spec.view_parameters)
        if spec.executable == 'seaking_sim' and 'rate' not in view and spec.parameters.get('rate') in (0, 0.0):
            view['rate'] = 1.0
        for key, value in view.items():
            if f'{spec.name}.{key}' not in given:
                spec.parameters[key] = value
                if key == 'rate' and spec.executable == 'seaking_sim':
                    changed.append((spec.name, float(value)))
    return changed


def sensor_presets() -> dict[str, Path]:
    """The sensor presets of the package's ``config/sensors/`` (first of each name), by name."""
    from sonar_tracking.resources import config_dirs
    found: dict[str, Path] = {}
    for d in config_dirs():
        for p in sorted((d / 'sensors').glob('*.yaml')) if (d / 'sensors').is_dir() else ():
            found.setdefault(p.stem, p)
    return found


def _is_preset(path: Path) -> bool:
    from sonar_tracking.resources import config_dirs
    folders = {(d / 'sensors').resolve() for d in config_dirs() if (d / 'sensors').is_dir()}
    return path.resolve().parent in folders


def apply_preset(config: StackConfig, preset: str) -> Path:
    """Give every node whose parameter file is a sensor preset of the package the preset ``preset``
    instead: a name of ``config/sensors/`` or a path to a preset file. Returns the file."""
    known = sensor_presets()
    path = known.get(preset[:-5] if preset.endswith('.yaml') else preset)
    if path is None:
        path = Path(preset)
        if not (path.suffix in ('.yaml', '.yml') and path.is_file()):
            raise StackError(f'--preset {preset}: no such sensor preset; the package has {", ".join(known) or "none"}, '
                             'or give the path of a preset file')
    chosen = [spec for spec in config.nodes if spec.params_file is not None and _is_preset(spec.params_file)]
    if not chosen:
        raise StackError(f'--preset {preset}: no node of this stack reads a sensor preset (a file of config/sensors/); '
                         'set params_file in the stack file instead')
    for spec in chosen:
        spec.params_file = path
    return path


def add_replay(config: StackConfig, args: str) -> NodeSpec:
    """Add ``bag_replay ARGS`` as the stack's last node: it starts once every node takes input
    (``wait_ready``), waits for the stack's readers of :data:`REPLAY_WAIT`, and its end stops the stack."""
    if config.namespace != '/':
        raise StackError(f'--replay: the stack runs in {config.namespace}, but a bag replays its topics under '
                         'their recorded, absolute names (/sonar/sector): run it in the root namespace')
    argv = shlex.split(args)
    if not argv:
        raise StackError('--replay needs a bag: --replay "BAG [bag_replay options]"')
    extra = argv if '--wait-for' in argv else [*argv, '--wait-for', *REPLAY_WAIT]
    spec = NodeSpec(name='bag_replay', executable='bag_replay', on_exit='stop', extra_args=extra, wait_ready=True)
    config.nodes.append(spec)
    return spec


def node_name(spec: NodeSpec) -> str:
    """The fully qualified name of the node a child runs (its executable's name, or ``__node`` remapped)."""
    return _join(spec.namespace, str(spec.remappings.get('__node', spec.executable)))


def move(config: StackConfig, namespace: str) -> None:
    """Put the whole stack, every node namespace included, under ``namespace``."""
    outer = _join('/', _namespace(namespace, '--namespace'))
    config.namespace = _join(outer, config.namespace.lstrip('/'))
    for spec in config.nodes:
        spec.namespace = _join(outer, spec.namespace.lstrip('/'))


def check_params_files(config: StackConfig) -> None:
    """StackError if a node runs outside the root namespace with a parameter file whose section for it
    is keyed by its bare name (``seaking_sim:``), which ROS applies in the root namespace only: the
    node would run on its defaults. Such sections must be keyed ``/**/seaking_sim:``."""
    from sonar_tracking.io import param_files
    for spec in config.nodes:
        if spec.params_file is None or spec.namespace == '/':
            continue
        try:
            stale = param_files.root_only_sections(param_files.load(spec.params_file), spec.executable)
        except param_files.ParamFileError as exc:
            raise StackError(str(exc)) from None
        if stale:
            raise StackError(f'{spec.params_file}: section {stale[0].lstrip("/")}: applies in the root namespace only, '
                             f'but {spec.name} runs in {spec.namespace} and would start on its defaults; key the '
                             f'section /**/{spec.executable}: so it applies in any namespace')


def command(spec: NodeSpec) -> list[str]:
    """The child's command line: ``python -m <module> [args] --ros-args ...``."""
    module = _entry_points()[spec.executable]
    cmd = [sys.executable, '-m', module, *spec.extra_args, '--ros-args']
    if spec.namespace != '/':
        cmd += ['-r', f'__ns:={spec.namespace}']
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
        self.proc = subprocess.Popen(command(self.spec), stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, bufsize=1, start_new_session=True, env=env,
                                     preexec_fn=process.child_dies_with_parent())
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
    """The stack's own rclpy node (``sonar_stack`` in the stack's namespace): counts subscribers for
    ``wait_for``, follows the status of the stack's nodes and publishes the stack's own on
    ``sonar_stack/status`` (module docstring), spun by a thread of its own."""

    def __init__(self, namespace: str, watched: list[str], say) -> None:
        from sonar_tracking.ros.runtime import configure_dds
        configure_dds()
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from sonar_tracking.ros.status import NodeStatus, StatusWatch
        self.say = say
        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('sonar_stack', namespace=namespace, context=self.context)
        self.watch = StatusWatch(self.node, watched)
        self.status = NodeStatus(self.node)
        self._shown: str | None = None
        self._publish()
        self.node.create_timer(0.1, self._publish)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, name='sonar_stack_probe', daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # noqa: BLE001 - the context was shut down under it at the end
            pass

    def _publish(self) -> None:
        from sonar_tracking.ros.status import LEARNING, STARTING
        state = self.watch.state()
        records = [r for r in self.watch.records.values() if r is not None]
        left = max([float(r.get('seconds_left', 0.0)) for r in records if r['state'] == LEARNING], default=0.0)
        nodes = {name: (st or STARTING) for name, st in self.watch.states().items()}
        detail = self.describe(nodes)
        self.status.set(state, left, detail, nodes=nodes)
        if state != self._shown:
            self._shown = state
            self.say(f'stack {state}: {detail}')

    def describe(self, nodes: dict | None = None) -> str:
        """The state of each node of the stack, in words."""
        from sonar_tracking.ros.status import STARTING
        nodes = {name: (st or STARTING) for name, st in self.watch.states().items()} if nodes is None else nodes
        return ', '.join(f'{name.rsplit("/", 1)[-1]} {st}' for name, st in sorted(nodes.items())) or 'no nodes'

    def takes_input(self) -> bool:
        """Whether no node of the stack says ``starting`` (every one takes input)."""
        from sonar_tracking.ros.status import STARTING
        return self.watch.state() != STARTING

    def ready(self, wait_for: dict) -> bool:
        return all(self.node.count_subscribers(topic) >= n for topic, n in wait_for.items())

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.thread.join(timeout=2.0)
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
    waits = {spec.name: {resolve_name(t, spec.namespace): n for t, n in spec.wait_for.items()} for spec in specs}
    if record_dir is not None:
        # The recorder starts first, and nodes that wait for listeners also wait for it.
        topics = [resolve_name(t, config.namespace) for t in config.record_topics]
        recorder = NodeSpec(name='bag_record', executable='bag_record', on_exit='stop',
                            extra_args=['-o', str(record_dir), *topics])
        late = _late_topics(topics, config.namespace)
        if late and any(spec.wait_for for spec in specs):
            say('bag_record subscribes to ' + ', '.join(late) + ' only once they are published (it knows the '
                "package's topics in the root namespace only): nobody waits for it there, and the bag may miss "
                'their first messages')
        for spec in specs:
            if spec.wait_for or spec.wait_ready:
                for topic in topics:
                    if topic not in late:
                        waits[spec.name][topic] = waits[spec.name].get(topic, 0) + 1
        specs.insert(0, recorder)
        waits[recorder.name] = {}
    viewer = interrupted = None
    if view is not None:  # waited topics the view listens to get one more listener
        from sonar_tracking.cli.view import TOPICS
        listens = {resolve_name(t, config.namespace) for t in TOPICS}
        waits = {name: {t: n + (t in listens) for t, n in w.items()} for name, w in waits.items()}
        interrupted = threading.Event()  # Ctrl-C or SIGTERM, as against the pipeline ending by itself
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda *a: (interrupted.set(), stop.set()))
        # Started here, outside the pipeline's children, so that it outlives them.
        viewer = Child(view_spec(config, view), lock)
        say(f'started sonar_view (pid {viewer.proc.pid})')
    for spec in specs:
        if spec.params_file is not None:
            say(f'{spec.name} reads parameters from {spec.params_file}')
    watched = [node_name(spec) for spec in specs if spec.executable in STATUS_EXECUTABLES]
    if viewer is None:
        return _run(config, specs, waits, grace, say, lock, stop, watched)
    status = None
    try:
        status = _run(config, specs, waits, grace, say, lock, stop, watched)
    finally:
        _keep_view(viewer, interrupted, say, grace, linger=status is not None)
    return status


def _keep_view(viewer: Child, interrupted: threading.Event, say, grace: float, linger: bool) -> None:
    """After the pipeline stopped: unless stopped by a signal (or ``linger`` is False), keep the view
    serving the run until Ctrl-C, SIGTERM or its own exit; then stop it."""
    if linger and not interrupted.is_set() and viewer.proc.poll() is None:
        say('the pipeline has stopped; sonar_view keeps the whole run for the browser (its address is the '
            '"view:" line above): Ctrl-C ends it')
        while not interrupted.wait(0.2) and viewer.proc.poll() is None:
            pass
    code = viewer.proc.poll()
    if code is not None:
        say(f'sonar_view exited with status {code}')
        return
    viewer.signal(signal.SIGINT)
    try:
        viewer.proc.wait(grace)
    except subprocess.TimeoutExpired:
        say(f'sonar_view did not stop within {grace:g} s: killed')
        viewer.signal(signal.SIGKILL)
        viewer.proc.wait()


def _late_topics(topics: list[str], namespace: str) -> list[str]:
    """Package topics moved into ``namespace``, which ``bag_record`` subscribes to only once they are
    published: a node waiting for the recorder to listen there before it publishes would wait forever."""
    from sonar_tracking.cli.bag_record import PACKAGE_TOPICS
    prefix = namespace.rstrip('/')
    return [t for t in topics if prefix and t not in PACKAGE_TOPICS and t.startswith(prefix + '/')
            and t[len(prefix):] in PACKAGE_TOPICS]


def _run(config: StackConfig, specs: list[NodeSpec], waits: dict, grace: float, say, lock: threading.Lock,
         stop: threading.Event, watched: list[str] | None = None) -> int:
    children: list[Child] = []
    graph = _GraphProbe(config.namespace, watched or [], say)
    deferred: list[NodeSpec] = []      # wait_ready: started by the watch loop once every node takes input
    status = 0
    try:
        for spec in specs:
            if spec.wait_ready:
                say(f'{spec.name} waits for every node of the stack to take input')
                deferred.append(spec)
                continue
            wait_for = waits[spec.name]
            if wait_for:
                say(f'{spec.name} waits for subscribers: ' + ', '.join(f'{t} >= {n}' for t, n in wait_for.items()))
                while not stop.is_set() and not graph.ready(wait_for):
                    time.sleep(0.05)
                if stop.is_set():
                    break
            children.append(Child(spec, lock))
            say(f'started {spec.name} (pid {children[-1].proc.pid})')
        status = _watch(config, children, deferred, waits, graph, say, lock, stop)
    finally:
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
        graph.close()
    return status


def _watch(config: StackConfig, children: list[Child], deferred: list[NodeSpec], waits: dict, graph: _GraphProbe,
           say, lock: threading.Lock, stop: threading.Event) -> int:
    """Start the deferred children once every node takes input, and apply the exit policies until
    the stack stops; returns the stack's exit status."""
    status = 0
    gone: set[str] = set()
    while not stop.is_set():
        time.sleep(0.1)
        if deferred and graph.takes_input():
            for spec in [s for s in deferred if graph.ready(waits[s.name])]:
                deferred.remove(spec)
                children.append(Child(spec, lock))
                say(f'started {spec.name} (pid {children[-1].proc.pid}): every node takes input ({graph.describe()})')
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
    return status


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``sonar_stack``."""
    parser = argparse.ArgumentParser(prog='sonar_stack', description=__doc__.split('\n\n')[0], allow_abbrev=False,
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog='e.g. sonar_stack harbour --namespace /auv1 --set seaking_sim.duration=30\n'
                                            '     sonar_stack recording --preset aris_didson --record out/run\n'
                                            '     sonar_stack recording_active --preset micron_seaking '
                                            '--replay rec_sectors --record out/run')
    parser.add_argument('stack', nargs='?',
                        help='stack name or file: harbour, fls, stack_harbour.yaml, path/to/my.yaml')
    parser.add_argument('--config', help='stack file, or the name of one in the package config (as STACK)')
    parser.add_argument('--set', action='append', default=[], metavar='NODE.PARAM=VALUE',
                        help='set a parameter of a node of the stack (repeatable; the value is YAML)')
    parser.add_argument('--namespace', metavar='NS', help='run the whole stack in this namespace, e.g. /auv1')
    parser.add_argument('--record', type=Path, default=None, metavar='DIR', help='also record a bag into DIR')
    parser.add_argument('--view', nargs='?', const='', default=None, metavar='ARGS',
                        help='also run sonar_view, the browser view (ARGS: its options, quoted)')
    parser.add_argument('--preset', metavar='SENSOR',
                        help='sensor preset for the nodes that read one: config/sensors/SENSOR.yaml ('
                             + ', '.join(sensor_presets()) + ') or a preset file, e.g. sonar_stack recording '
                             '--preset aris_didson')
    parser.add_argument('--replay', metavar='"BAG [OPTIONS]"',
                        help='replay the bag into the stack once every node takes input (bag_replay BAG OPTIONS, '
                             'quoted); the stack stops when the replay ends')
    parser.add_argument('--dry-run', action='store_true', help="print the children's command lines and exit")
    parser.add_argument('--list', action='store_true', help='list the stack files shipped with the package')
    argv = sys.argv[1:] if argv is None else list(argv)
    ros_args: list[str] = []
    if '--ros-args' in argv:
        i = argv.index('--ros-args')
        argv, ros_args = argv[:i], argv[i + 1:]
    args = parser.parse_args(argv)
    try:
        namespace = _namespace_from(args.namespace, ros_args)
    except StackError as exc:
        parser.error(str(exc))
    if args.list:
        for p in shipped_stacks():
            print(p)
        return 0
    if (args.stack is None) == (args.config is None):
        parser.error('give a stack: a name or file, or --config FILE (one of them)')
    try:
        path = find_stack(args.stack or args.config)
        config = load_stack(path)
        if args.preset is not None:
            apply_preset(config, args.preset)
        live = apply_view_settings(config, args.set) if args.view is not None else []
        apply_settings(config, args.set)
        if namespace is not None:
            move(config, namespace)
        if args.replay is not None:
            add_replay(config, args.replay)
        check_params_files(config)
    except StackError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if args.dry_run:
        print(f'# {path}' + (f' in {config.namespace}' if config.namespace != '/' else ''))
        for spec in config.nodes:
            print(shlex.join(command(spec)))
        return 0
    if args.record is not None and args.record.exists():
        print(f'error: {args.record} exists already', file=sys.stderr)
        return 2
    if args.view is not None and not _has_view():
        from sonar_tracking.cli.sonar_view import MISSING
        print(f'error: {MISSING}', file=sys.stderr)
        return 2
    for name, rate in live:
        pace = 'in real time (rate 1), as the sensor would' if rate == 1.0 else f'at rate {rate:g} of real time'
        print(f'[sonar_stack] --view: {name} runs {pace}, so that the page keeps up; --set {name}.rate=0 runs it '
              f'at full speed', flush=True)
    return run(config, args.record, view=args.view)


def _namespace_from(namespace: str | None, ros_args: list[str]) -> str | None:
    """The stack's namespace from ``--namespace`` and ``--ros-args -r __ns:=NS`` (the ``ros2 run``
    habit); StackError for any other ROS argument (parameters go through ``--set``) or two namespaces."""
    args = [a for a in ros_args if a != '--']
    remaps = []
    i = 0
    while i < len(args):
        if args[i] in ('-r', '--remap') and i + 1 < len(args):
            remaps.append(args[i + 1])
            i += 2
        elif args[i] in ('--ros-args',):
            i += 1
        else:
            raise StackError(f'--ros-args: sonar_stack takes only -r __ns:=NS there, not {args[i]!r} (parameters: '
                             '--set NODE.PARAM=VALUE; remappings: the stack file)')
    for remap in remaps:
        key, sep, value = remap.partition(':=')
        if key != '__ns' or not sep or not value:
            raise StackError(f'--ros-args -r {remap}: sonar_stack takes only -r __ns:=NS (node remappings go in '
                             'the stack file)')
        if namespace is not None and namespace.rstrip('/') != value.rstrip('/'):
            raise StackError(f'two namespaces: --namespace {namespace} and -r __ns:={value}')
        namespace = value
    return namespace


def _has_view() -> bool:
    import importlib.util
    try:
        return importlib.util.find_spec('rerun') is not None
    except (ImportError, ValueError):
        return False


if __name__ == '__main__':
    sys.exit(main())

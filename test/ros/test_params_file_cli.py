"""The ``ros2 run`` habit: ``NODE --ros-args -r __ns:=/x --params-file FILE`` gives the file's values,
read back through the node's parameter services (the rcl path ``ros2 param get`` takes), for every node
section of the shipped node, simulator and sensor files; and a node warns about names it does not know."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from sonar_tracking.io import param_files
from sonar_tracking.resources import config_path

pytestmark = pytest.mark.ros

NODES = {'seaking_sim', 'active_detector', 'imm_ipda_tracker', 'fls_features', 'gpf_tracker'}


def shipped_sections() -> list[tuple[str, str]]:
    """``(file relative to config/, node)`` for every node section of the shipped parameter files."""
    root = config_path('imm_ipda.yaml').parent
    files = sorted(p for p in root.glob('*.yaml')
                   if p.name != 'desired_density.yaml' and not p.name.startswith('stack_'))
    files += sorted(root.glob('sensors/*.yaml'))
    out = []
    for path in files:
        for pattern, _ in param_files.sections(param_files.load(path)):
            node = pattern.rsplit('/', 1)[-1]
            if node in NODES:
                out.append((str(path.relative_to(root)), node))
    return out


SECTIONS = shipped_sections()


def executable(node: str) -> list[str]:
    """What ``ros2 run sonar_tracking NODE`` runs: ``lib/sonar_tracking/NODE`` of the first prefix on
    ``AMENT_PREFIX_PATH`` that has it (the suite runs with the colcon install sourced), else the module."""
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        path = Path(prefix) / 'lib' / 'sonar_tracking' / node
        if path.is_file():
            return [str(path)]
    return [sys.executable, '-m', f'sonar_tracking.nodes.{node}']


def start(node: str, namespace: str, *params_files, extra: tuple[str, ...] = ()) -> subprocess.Popen:
    cmd = [*executable(node), '--ros-args', '-r', f'__ns:={namespace}', *extra]
    for f in params_files:
        cmd += ['--params-file', str(f)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env=dict(os.environ, SONAR_TRACKING_DIE_WITH_PARENT='1'))


def stop(proc: subprocess.Popen) -> str:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        return proc.communicate(timeout=20)[1]
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        return proc.communicate()[1]


def get_parameters(ros, fqn: str, names: list[str]) -> dict:
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python
    client = ros.node.create_client(GetParameters, f'{fqn}/get_parameters')
    try:
        ros.wait(lambda: client.service_is_ready(), 120, f'{fqn}/get_parameters')
        # The parameter services exist from the node's first line; it answers once it spins, after
        # its warm-up, which four nodes starting at once on a loaded machine made take over 20 s.
        reply = ros.call(client, GetParameters.Request(names=names), timeout=120)
    finally:
        ros.node.destroy_client(client)
    return {n: parameter_value_to_python(v) for n, v in zip(names, reply.values, strict=True)}


def same(a, b) -> bool:
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return a == b and type(a) is type(b) if isinstance(a, (bool, str)) else float(a) == float(b)


def test_every_shipped_section_applies_under_a_namespace(ros):
    """Four nodes at a time, each in a namespace of its own: every value of its section is the file's."""
    root = config_path('imm_ipda.yaml').parent
    checked = 0
    for first in range(0, len(SECTIONS), 4):
        batch = list(enumerate(SECTIONS[first:first + 4], first))
        procs = {i: start(node, f'/auv{i}/deep', root / rel) for i, (rel, node) in batch}
        try:
            for i, (rel, node) in batch:
                want = param_files.parameters_for(param_files.load(root / rel), node, f'/auv{i}/deep')
                assert want, f'{rel}: no section applies to {node} under /auv{i}/deep'
                got = get_parameters(ros, f'/auv{i}/deep/{node}', sorted(want))
                wrong = {n: (want[n], got[n]) for n in want if not same(want[n], got[n])}
                assert not wrong, f'{rel} [{node}] under /auv{i}/deep: (file, node) {wrong}'
                checked += len(want)
        finally:
            logs = {i: stop(p) for i, p in procs.items()}
        for i, _ in batch:
            assert 'unknown parameter' not in logs[i], logs[i]
    assert len(SECTIONS) >= 19 and checked > 150


def test_a_node_warns_about_names_it_does_not_know(ros, tmp_path):
    """A misspelt name in the node's section is logged with the node's name; the file's other values hold."""
    typo = tmp_path / 'typo.yaml'
    typo.write_text('/**/imm_ipda_tracker:\n  ros__parameters:\n    detection.probabilty: 0.8\n'
                    '    detection.probability: 0.7\n/**/fls_features:\n  ros__parameters:\n    not_mine: 1\n')
    proc = start('imm_ipda_tracker', '/auv1', typo)
    try:
        got = get_parameters(ros, '/auv1/imm_ipda_tracker', ['detection.probability'])
    finally:
        log = stop(proc)
    assert got == {'detection.probability': 0.7}
    assert 'unknown parameter(s) for /auv1/imm_ipda_tracker, ignored: detection.probabilty' in log, log
    assert 'not_mine' not in log   # another node's section is not this node's business

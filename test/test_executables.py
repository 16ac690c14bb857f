"""Every registered executable, as colcon installed it into install/sonar_tracking/lib/sonar_tracking
(what ``ros2 run`` executes after ``source install/setup.bash``), starts.

Nodes must appear in the ROS graph and stop cleanly on SIGINT; command-line tools must answer ``--help``.
``make test`` runs ``colcon build`` first; run ``make build`` before calling pytest by hand.
"""
from __future__ import annotations

import ast
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from sonar_tracking import process

ROOT = Path(__file__).resolve().parents[1]
INSTALL = Path(os.environ.get('SONAR_TRACKING_INSTALL', ROOT / 'install'))
LIBDIR = INSTALL / 'sonar_tracking' / 'lib' / 'sonar_tracking'


def console_scripts() -> dict[str, str]:
    """``{name: module}`` from the CONSOLE_SCRIPTS list in setup.py."""
    tree = ast.parse((ROOT / 'setup.py').read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '') == 'CONSOLE_SCRIPTS':
            entries = ast.literal_eval(node.value)
            return {e.split('=')[0].strip(): e.split('=')[1].split(':')[0].strip() for e in entries}
    raise AssertionError('setup.py has no CONSOLE_SCRIPTS list')


SCRIPTS = console_scripts()


def sourced(cmd: str) -> list[str]:
    return ['bash', '-c', f'source {INSTALL}/setup.bash && exec {cmd}']


@pytest.fixture(scope='module')
def installed():
    if not (INSTALL / 'setup.bash').exists():
        pytest.fail(f'{INSTALL} has no colcon install; run `make build` (make test does it)')
    return LIBDIR


def test_every_registered_executable_is_installed(installed):
    assert sorted(p.name for p in installed.iterdir()) == sorted(SCRIPTS)


@pytest.mark.parametrize('name', sorted(n for n, m in SCRIPTS.items() if not m.startswith('sonar_tracking.nodes.')))
def test_tool_answers_help(installed, name):
    r = subprocess.run(sourced(f'{installed / name} --help'), capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert f'usage: {name}' in r.stdout


@pytest.mark.ros
@pytest.mark.parametrize('name', sorted(n for n, m in SCRIPTS.items() if m.startswith('sonar_tracking.nodes.')))
def test_node_starts_and_stops_on_sigint(installed, name, graph_node):
    # A name of its own: the graph may still list nodes of earlier tests' processes.
    probe = f'{name}_exe_{os.getpid()}'
    proc = subprocess.Popen(sourced(f'{installed / name} --ros-args -r __node:={probe}'), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=process.child_dies_with_parent())
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            assert proc.poll() is None, f'{name} exited early: {proc.communicate()[1]}'
            if probe in [n for n, _ in graph_node.get_node_names_and_namespaces()]:
                break
            time.sleep(0.2)
        else:
            pytest.fail(f'{name} did not appear in the ROS graph within 30 s')
        os.killpg(proc.pid, signal.SIGINT)     # may arrive while the node still warms its kernels up
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
        assert 'Traceback' not in err, err
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()

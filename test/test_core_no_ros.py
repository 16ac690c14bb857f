"""The layers below ``ros`` never need ROS: every module of ``core``, ``sim``, ``studies``, ``msgs`` and
``io`` imports with rclpy and the message packages made unimportable (which of our own layers each may
import is checked in ``test_architecture.py``)."""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

BLOCKER = textwrap.dedent('''
    import importlib, importlib.abc, pkgutil, sys

    def forbidden(name):
        top = name.split('.')[0]
        return (top in ('rclpy', 'rmw', 'rcl', 'rcutils', 'std_srvs', 'builtin_interfaces', 'ament_index_python',
                        'rosidl_runtime_py', 'rpyutils')
                or top.endswith('_msgs') or top.startswith('rosidl_') or top.startswith('rcl_'))

    class Blocker(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path, target=None):
            if forbidden(name):
                raise ImportError(f'must not import {name}')
            return None

    sys.meta_path.insert(0, Blocker())
    BODY
''')


def run(body: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-c', BLOCKER.replace('BODY', textwrap.dedent(body))], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize('layer', ['core', 'sim', 'studies', 'msgs', 'io'])
def test_every_module_of_the_layer_imports_without_ros(layer):
    r = run(f'''
        import sonar_tracking.{layer} as layer
        names = [m.name for m in pkgutil.walk_packages(layer.__path__, 'sonar_tracking.{layer}.')]
        for name in names:
            importlib.import_module(name)
        print(len(names), 'modules')
    ''')
    assert r.returncode == 0, r.stderr
    assert int(r.stdout.split()[0]) >= 2


def test_the_blocker_really_blocks():
    """Control: the same harness refuses rclpy and message packages, so the test above can fail."""
    for mod in ('rclpy', 'sensor_msgs.msg', 'std_srvs.srv', 'sonar_tracking.ros'):
        r = run(f'import {mod}')
        assert r.returncode != 0 and 'must not import' in r.stderr, mod

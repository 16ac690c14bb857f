"""projected_sonar_adapter without its message package: exit with the reason, or wait only when asked.

The child blocks ``import marine_acoustic_msgs`` while a marker file exists (a meta path finder
installed before the node starts), so the test runs whether or not the package is built here."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest

from sonar_tracking.nodes.projected_sonar_adapter import EXIT_NO_INTERFACES

pytestmark = pytest.mark.ros

CHILD = textwrap.dedent('''
    import importlib.abc, os, sys

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split('.')[0] == 'marine_acoustic_msgs' and os.path.exists(sys.argv[1]):
                raise ModuleNotFoundError(f'No module named {name!r} (blocked by the test)')
            return None

    sys.meta_path.insert(0, Block())
    from sonar_tracking.nodes.projected_sonar_adapter import main
    sys.exit(main(sys.argv[2:]))
''')


def start(marker, *params: str) -> subprocess.Popen:
    cmd = [sys.executable, '-c', CHILD, str(marker), '--ros-args', '-r', '__ns:=/adapter_test']
    for p in params:
        cmd += ['-p', p]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env=dict(os.environ, SONAR_TRACKING_DIE_WITH_PARENT='1'))


def test_without_the_message_package_it_exits_with_the_reason(tmp_path):
    marker = tmp_path / 'block'
    marker.touch()
    proc = start(marker)
    try:
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == EXIT_NO_INTERFACES, err
    assert 'marine_acoustic_msgs is not importable' in err and 'build_interfaces' in err, err
    assert 'wait_for_interfaces' in err and 'Traceback' not in err, err


def test_asked_to_wait_it_stays_up_and_subscribes_once_the_package_imports(ros, tmp_path):
    """The node waits, says so in /diagnostics, and subscribes ``sonar_image`` once the import
    succeeds (the test lifts the block: as a package built meanwhile into a sourced prefix)."""
    pytest.importorskip('marine_acoustic_msgs.msg', reason='marine_acoustic_msgs not built here')
    from diagnostic_msgs.msg import DiagnosticArray
    inputs = []

    def on_diag(msg):
        inputs.extend(kv.value for st in msg.status for kv in st.values if kv.key == 'input')
    sub = ros.node.create_subscription(DiagnosticArray, '/adapter_test/diagnostics', on_diag, 50)
    marker = tmp_path / 'block'
    marker.touch()
    proc = start(marker, 'wait_for_interfaces:=true')

    def subscribed():
        try:
            names = ros.node.get_subscriber_names_and_types_by_node('projected_sonar_adapter', '/adapter_test')
        except Exception:   # not discovered yet
            return False
        return any(t == '/adapter_test/sonar_image' for t, _ in names)
    try:
        ros.wait(lambda: 'waiting for marine_acoustic_msgs' in inputs, 120, 'the waiting report')
        assert proc.poll() is None and not subscribed()
        marker.unlink()
        ros.wait(subscribed, 60, 'the sonar_image subscription')
        ros.wait(lambda: inputs[-1:] == ['sonar_image'], 30, 'the input report')
    finally:
        ros.node.destroy_subscription(sub)
        os.killpg(proc.pid, signal.SIGINT)
        err = proc.communicate(timeout=30)[1]
    assert proc.returncode == 0, err
    assert 'waiting for it' in err, err

"""No process that a test or ``sonar_stack`` starts outlives its parent, however the parent ends: the
parent killed with SIGKILL (as a CI timeout kills a test run), its children end too."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from sonar_tracking import process

pytestmark = pytest.mark.ros

TEST_DIR = Path(__file__).resolve().parents[1]

# A test run that starts a node with the suite's own ``launch`` fixture and then waits to be killed.
PROBE = '''
import threading


def test_probe(launch):
    proc = launch('seaking_sim', 'rate:=1.0')
    print(f'NODE_PID {proc.pid}', flush=True)
    threading.Event().wait(600)   # until the test that started this run kills it
'''


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended and not yet reaped by its new parent, does not)."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


class Output:
    """The merged output of a process, read by a thread of its own."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.text = ''
        self._thread = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._thread.start()

    def _read(self, proc: subprocess.Popen) -> None:
        for line in proc.stdout:
            self.text += line


def child(cmd: list[str], **kwargs) -> subprocess.Popen:
    """A child of this test that ends with it, in a session of its own, its output merged and read as text."""
    return subprocess.Popen(cmd, start_new_session=True, preexec_fn=process.child_dies_with_parent(),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kwargs)


def kill_orphans(pids: list[int]) -> None:
    for pid in pids:
        if alive(pid):
            os.killpg(pid, signal.SIGKILL)    # a failed test leaves nothing behind either


def test_a_test_run_killed_with_sigkill_leaves_no_node_running(tmp_path, ros):
    (tmp_path / 'test_probe.py').write_text(PROBE)
    (tmp_path / 'pytest.ini').write_text('[pytest]\n')
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(TEST_DIR), os.environ.get('PYTHONPATH', '')]))
    run = child([sys.executable, '-m', 'pytest', '-s', '-q', '-p', 'conftest', '-p', 'no:cacheprovider',
                  'test_probe.py'], cwd=tmp_path, env=env)
    out = Output(run)
    node: list[int] = []
    try:
        ros.wait(lambda: 'NODE_PID' in out.text or run.poll() is not None, 60.0, 'the probe run to start its node')
        node = [int(re.search(r'NODE_PID (\d+)', out.text).group(1))]
        ros.wait(lambda: 'seaking_sim' in ros.node.get_node_names(), 60.0, 'the node in the ROS graph')
        os.kill(run.pid, signal.SIGKILL)
        run.wait()
        ros.wait(lambda: not alive(node[0]), 30.0, 'the node of the killed run to end')
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        kill_orphans(node)


def test_a_sonar_stack_killed_with_sigkill_leaves_no_child_running(tmp_path, ros):
    stack = tmp_path / 'stack.yaml'
    stack.write_text('nodes:\n'
                     '  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}}\n'
                     '  active_detector: {}\n')
    run = child([sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', '--config', str(stack), '--record',
                 str(tmp_path / 'bag')])
    out = Output(run)
    children: dict[str, int] = {}
    try:
        ros.wait(lambda: len(re.findall(r'started \S+ \(pid \d+\)', out.text)) == 3 or run.poll() is not None,
                 60.0, 'the stack to start bag_record, seaking_sim and active_detector')
        children = {m.group(1): int(m.group(2)) for m in re.finditer(r'started (\S+) \(pid (\d+)\)', out.text)}
        assert set(children) == {'bag_record', 'seaking_sim', 'active_detector'}, out.text
        ros.wait(lambda: {'seaking_sim', 'active_detector'} <= set(ros.node.get_node_names()), 60.0,
                 'the nodes in the ROS graph')
        os.kill(run.pid, signal.SIGKILL)
        run.wait()
        ros.wait(lambda: not any(alive(pid) for pid in children.values()), 30.0,
                 f'the children of the killed stack to end: {children}')
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        kill_orphans(list(children.values()))

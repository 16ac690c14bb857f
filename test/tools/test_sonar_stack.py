"""sonar_stack: children with prefixed logs, exit policies, clean stop, no orphans."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

import pytest

from sonar_tracking.tools.sonar_stack import StackError, command, load_stack

pytestmark = pytest.mark.ros


def write(tmp_path, text):
    p = tmp_path / 'stack.yaml'
    p.write_text(text)
    return p


def start(path, *args):
    return subprocess.Popen([sys.executable, '-m', 'sonar_tracking.tools.sonar_stack', '--config', str(path), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead too.
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().split()[2] != 'Z'
    except FileNotFoundError:
        return False


def pids(out):
    return {m.group(1): int(m.group(2)) for m in re.finditer(r'started (\S+) \(pid (\d+)\)', out)}


def read_until(proc, pattern, timeout=30.0):
    """Read the stack's output until a line matches; returns everything read."""
    text, deadline = '', time.monotonic() + timeout
    os.set_blocking(proc.stdout.fileno(), False)
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line:
            text += line
            if re.search(pattern, text):
                return text
        else:
            time.sleep(0.05)
    raise AssertionError(f'no {pattern!r} in:\n{text}')


def test_runs_until_the_simulator_finishes_with_prefixed_logs(tmp_path):
    path = write(tmp_path, '''
nodes:
  seaking_sim:
    parameters: {scenario: scenario1, rate: 4.0, duration: 3.0, shutdown_when_done: true}
  active_detector:
    params_file: active_detector.yaml
    parameters: {esc.enabled: false}
''')
    proc = start(path)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, out
    assert re.search(r'^\[seaking_sim\] .*finished after 3 sectors', out, re.M)
    assert re.search(r'^\[active_detector\] .*ESC off', out, re.M)
    assert 'seaking_sim exited with status 0: stopping the stack' in out
    for name, pid in pids(out).items():
        assert not alive(pid), name


def test_sigterm_stops_every_child_within_five_seconds(tmp_path):
    path = write(tmp_path, '''
nodes:
  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}}
  active_detector: {}
''')
    proc = start(path)
    out = read_until(proc, r'\[active_detector\].*threshold')
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    rest, _ = proc.communicate(timeout=10)
    assert time.monotonic() - t0 < 5.0
    assert proc.returncode == 0
    for name, pid in pids(out + rest).items():
        assert not alive(pid), name


def test_a_dead_child_is_restarted_or_stops_the_stack(tmp_path):
    path = write(tmp_path, '''
max_restarts: 1
nodes:
  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}, on_exit: restart}
  active_detector: {on_exit: stop}
''')
    proc = start(path)
    out = read_until(proc, r'\[active_detector\].*threshold')
    first = pids(out)
    os.killpg(first['seaking_sim'], signal.SIGKILL)
    out += read_until(proc, r'restarting \(1/1\)')
    os.killpg(first['active_detector'], signal.SIGKILL)
    rest, _ = proc.communicate(timeout=20)
    assert 'active_detector exited with status -9: stopping the stack' in rest
    assert proc.returncode == 1


def test_a_killed_stack_leaves_no_orphans(tmp_path):
    path = write(tmp_path, '''
nodes:
  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}}
''')
    proc = start(path)
    out = read_until(proc, r'\[seaking_sim\].*SeaKing')
    child = pids(out)['seaking_sim']
    os.killpg(proc.pid, signal.SIGKILL)   # the stack only: its child is in a session of its own
    proc.wait()
    deadline = time.monotonic() + 10
    while alive(child) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(child)


@pytest.mark.parametrize('text, match', [
    ('nodes: {}', 'at least one node'),
    ('nodes: {x: {executable: no_such_node}}', 'unknown executable'),
    ('nodes: {seaking_sim: {on_exit: explode}}', 'on_exit must be one of'),
    ('nodes: {seaking_sim: {params_file: nowhere.yaml}}', 'not found'),
    ('nodes: {seaking_sim: {paramters: {}}}', 'unknown keys'),
])
def test_bad_stack_files_are_refused(tmp_path, text, match):
    with pytest.raises(StackError, match=match):
        load_stack(write(tmp_path, text))


def test_command_line_of_a_child(tmp_path):
    cfg = load_stack(write(tmp_path, '''
nodes:
  active_detector:
    params_file: active_detector.yaml
    parameters: {esc.density_source: best_track, sonar_pose: [1.0, 2.0, 0.0]}
    remappings: {/detections: /harbour/detections}
'''))
    cmd = command(cfg.nodes[0])
    assert cmd[1:3] == ['-m', 'sonar_tracking.nodes.active_detector']
    assert cmd[cmd.index('--params-file') + 1].endswith('config/active_detector.yaml')
    assert '-p' in cmd and 'esc.density_source:="best_track"' in cmd and 'sonar_pose:=[1.0, 2.0, 0.0]' in cmd
    assert '/detections:=/harbour/detections' in cmd

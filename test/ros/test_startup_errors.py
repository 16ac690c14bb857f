"""A node whose ROS arguments rcl cannot take (a parameter file it cannot parse, a malformed rule,
an unknown argument) ends with one line saying what to fix and exit status 2, not a traceback."""
from __future__ import annotations

import subprocess
import sys

import pytest

pytestmark = pytest.mark.ros

NODES = ('seaking_sim', 'active_detector', 'imm_ipda_tracker', 'fls_features', 'gpf_tracker',
         'projected_sonar_adapter')


def start(node: str, *ros_args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', f'sonar_tracking.nodes.{node}', '--ros-args', *ros_args],
                          capture_output=True, text=True, timeout=120)


def one_line(r: subprocess.CompletedProcess, node: str) -> str:
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and 'Traceback' not in r.stderr and len(lines) == 1, r.stderr
    assert lines[0].startswith(f'{node}: cannot start: '), lines[0]
    return lines[0]


@pytest.mark.parametrize('node', NODES)
def test_an_unparsable_parameter_file_is_one_line_naming_file_and_place(tmp_path, node):
    path = tmp_path / 'broken.yaml'
    path.write_text(f'{node}:\n  ros__parameters:\n    a: [1, 2\n')
    line = one_line(start(node, '--params-file', str(path)), node)
    assert str(path) in line and 'line 3' in line
    assert '/project/src' not in line     # rcl's source locations say nothing to a user


@pytest.mark.parametrize('text, says', [
    ('fls_features:\n  image.resolution: 0.1\n', 'ros__parameters'),
    (None, 'opening'),                                       # no such file
])
def test_a_parameter_file_rcl_refuses_is_one_line(tmp_path, text, says):
    path = tmp_path / 'params.yaml'
    if text is not None:
        path.write_text(text)
    line = one_line(start('fls_features', '--params-file', str(path)), 'fls_features')
    assert str(path) in line and says in line


@pytest.mark.parametrize('args, says', [
    (('-p', 'image.resolution'), "'-p image.resolution'"),
    (('--no-such-argument',), '--no-such-argument'),
])
def test_malformed_or_unknown_ros_arguments_are_one_line(args, says):
    line = one_line(start('fls_features', *args), 'fls_features')
    assert says in line

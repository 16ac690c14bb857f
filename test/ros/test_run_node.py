"""run_node, the main() of every node: Ctrl-C at any moment is a stop, a real error is not hidden."""
from __future__ import annotations

import subprocess
import sys

import pytest

pytestmark = pytest.mark.ros

# The factory stands in for a node constructor that is interrupted: rclpy's SIGINT handler shuts
# the context down, and the constructor's next call on it (a subscription) fails.
SCRIPT = '''
import rclpy
from sonar_tracking.ros.runtime import run_node

def factory():
    node = rclpy.create_node('run_node_probe')
    if {interrupt}:
        rclpy.shutdown()
    node.create_subscription(__import__('std_msgs.msg').msg.Empty, 'x', lambda m: None, 1)
    raise ValueError('a real error while building the node')

raise SystemExit(run_node(factory, []))
'''


@pytest.mark.parametrize('interrupt', [True, False])
def test_an_interrupted_start_is_a_clean_stop_and_a_real_error_is_raised(interrupt):
    r = subprocess.run([sys.executable, '-c', SCRIPT.format(interrupt=interrupt)], capture_output=True, text=True,
                       timeout=60)
    if interrupt:
        assert r.returncode == 0 and 'Traceback' not in r.stderr, r.stderr
    else:
        assert r.returncode == 1 and 'ValueError: a real error while building the node' in r.stderr, r.stderr


def test_a_hung_teardown_ends_the_process_with_its_status():
    """exit_if_teardown_hangs: a tool whose work is done leaves even if the teardown blocks (here: forever)."""
    hang = ('import threading\nfrom sonar_tracking.ros.runtime import exit_if_teardown_hangs\n'
            'exit_if_teardown_hangs(3, 0.2)\nthreading.Event().wait()\n')
    r = subprocess.run([sys.executable, '-c', hang], capture_output=True, text=True, timeout=60)
    assert r.returncode == 3 and 'ROS teardown took over 0.2 s' in r.stderr
    done = 'from sonar_tracking.ros.runtime import exit_if_teardown_hangs\nexit_if_teardown_hangs(3, 30.0)\n'
    r = subprocess.run([sys.executable, '-c', done], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stderr == ''     # a teardown that finishes exits as usual

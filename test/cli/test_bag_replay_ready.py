"""bag_replay --wait-for starts only once no node of the graph says it is ``starting`` on its status topic."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from sonar_tracking import process
from sonar_tracking.io.bags import BagWriter

pytestmark = pytest.mark.ros

S = 1_000_000_000
TOPIC = '/ready_test/value'


def value_bag(path, n: int) -> None:
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    w = BagWriter(path, 'mcap', sync=False)
    w.open()
    conn = w.add_connection(TOPIC, 'std_msgs/msg/Float64', typestore=ts)
    for k in range(n):
        w.write(conn, 1_700_000_000 * S + k * S // 10,
                ts.serialize_cdr(ts.types['std_msgs/msg/Float64'](data=float(k)), 'std_msgs/msg/Float64'))
    w.close()


def read_until(proc, pattern: str, timeout: float = 30.0) -> str:
    """Read the replayer's log (stderr) until a line matches; returns everything read."""
    text, deadline = '', time.monotonic() + timeout
    os.set_blocking(proc.stderr.fileno(), False)
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if line:
            text += line
            if re.search(pattern, text):
                return text
        elif proc.poll() is not None:
            break
        else:
            time.sleep(0.05)
    raise AssertionError(f'no {pattern!r} in:\n{text}')


def test_replay_waits_while_a_node_says_starting(tmp_path, ros):
    from std_msgs.msg import Float64, String
    node = ros.node
    me = node.get_fully_qualified_name()
    value_bag(tmp_path / 'bag', 5)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
    status = node.create_publisher(String, f'{me}/status', latched)
    got = []
    sub = node.create_subscription(Float64, TOPIC, lambda m: got.append(m.data),
                                   QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))

    def say(state):
        status.publish(String(data=json.dumps({'node': me, 'state': state, 'seconds_left': 0.0, 'detail': ''})))

    def replay(*args):
        return subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.bag_replay', str(tmp_path / 'bag'),
                                 '--wait-for', TOPIC, '--rate', '10', *args], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True,
                                preexec_fn=process.child_dies_with_parent())
    try:
        say('starting')
        # A node that never takes input: the replay gives up at --wait-timeout and says which (5 s:
        # the replay must discover the subscriber first, which took over 1 s on a loaded machine).
        proc = replay('--wait-timeout', '5')
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 1 and f'still not taking input at the end of --wait-timeout: {me} (starting)' in err
        assert got == []
        # It starts once the node takes input, and then every message arrives.
        proc = replay()
        read_until(proc, rf'waiting for nodes to take input: {me} \(starting\)')
        assert got == []
        say('learning')
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
        assert re.search(rf'every node takes input: {me} \(learning\)', err), err
        ros.wait(lambda: len(got) == 5, 10.0, 'every replayed message')
        assert got == [0.0, 1.0, 2.0, 3.0, 4.0]
    finally:
        node.destroy_subscription(sub)
        node.destroy_publisher(status)

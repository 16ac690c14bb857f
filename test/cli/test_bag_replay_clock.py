"""bag_replay's clock model: /clock only on request, from the replayed messages' header stamps (not their
receive times), never back within a pass, advancing between messages without passing the next stamp;
refused when another node publishes /clock; a missing or empty bag is a clear error."""
from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from sonar_tracking.cli import bag_replay
from sonar_tracking.io.bags import BagMessage, BagWriter

S = 1_000_000_000
EXIT_UNREADABLE, EXIT_CLOCK_TAKEN = 1, 3      # bag_replay's documented exit codes


# ---------------------------------------------------------------------- the model, on a wall clock of the test's
def test_stamps_set_the_clock_it_never_goes_back_and_stops_at_the_next_stamp():
    clock = bag_replay.ReplayClock(rate=2.0)
    assert clock.at(0.0) is None                       # nothing before the first stamped message
    assert clock.message(100 * S, wall=10.0, next_stamp=101 * S) == 100 * S
    assert clock.at(10.25) == 100 * S + S // 2         # 0.25 s of wall time at rate 2
    assert clock.at(10.5) == 101 * S and clock.at(12.0) == 101 * S      # capped at the next stamp
    assert clock.message(101 * S, wall=12.0, next_stamp=99 * S) == 101 * S
    assert clock.at(13.0) == 101 * S                   # the next stamp is earlier: the clock holds
    assert clock.message(99 * S, wall=13.0, next_stamp=105 * S) == 101 * S   # an earlier stamp: no step back
    assert clock.at(13.5) == 102 * S                   # advances from where it is, at the rate
    assert clock.message(103 * S, wall=13.6, next_stamp=None) == 103 * S
    assert clock.at(20.0) == 103 * S                   # no next stamp known: holds
    clock.new_pass()
    assert clock.at(21.0) is None
    assert clock.message(100 * S, wall=21.0, next_stamp=None) == 100 * S     # a new pass may go back


def test_fast_replay_steps_from_stamp_to_stamp():
    clock = bag_replay.ReplayClock(rate=None)
    clock.message(5 * S, wall=0.0, next_stamp=9 * S)
    assert clock.at(100.0) == 5 * S
    assert clock.message(9 * S, wall=100.0, next_stamp=None) == 9 * S


@pytest.mark.parametrize('little', [True, False])
def test_header_stamp_from_cdr_bytes(little):
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Image
    from std_msgs.msg import Float64
    msg = Image()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_123, 456_789
    data = serialize_message(msg)
    if not little:      # the same header as a big-endian writer encodes it
        data = b'\x00\x00\x00\x00' + (1_700_000_123).to_bytes(4, 'big') + (456_789).to_bytes(4, 'big') + data[12:]
    assert bag_replay.header_stamp(data) == 1_700_000_123 * S + 456_789
    assert bag_replay.stamp_reader(Image) is bag_replay.header_stamp and bag_replay.stamp_reader(Float64) is None
    assert bag_replay.header_stamp(serialize_message(Image())) is None    # a header nobody filled in
    assert bag_replay.header_stamp(data[:10]) is None


def test_the_next_stamp_is_looked_for_ahead_within_bounds():
    stamped, plain = (lambda d: int.from_bytes(d, 'little') or None), None
    msgs = [BagMessage('/a', 0, (1).to_bytes(4, 'little')), BagMessage('/b', 1, bytes(4)),
            BagMessage('/b', 2, bytes(4)), BagMessage('/a', 3, (7).to_bytes(4, 'little'))]
    out = list(bag_replay._with_stamps(iter(msgs), {'/a': stamped, '/b': plain}))
    assert [(m.timestamp, s, n) for m, s, n in out] == [(0, 1, 7), (1, None, None), (2, None, None), (3, 7, None)]
    far = [msgs[0]] + [msgs[1]] * bag_replay.LOOKAHEAD_MESSAGES + [msgs[3]]
    out = list(bag_replay._with_stamps(iter(far), {'/a': stamped, '/b': plain}))
    assert out[0][1:] == (1, None) and len(out) == len(far)     # beyond the lookahead: unknown, the clock holds


# ---------------------------------------------------------------------- through ROS
OFFSET = 1000 * S          # receive times lie 1000 s after the stamps: a clock of receive times is far off
T0 = 1_700_000_000 * S


def stamped_bag(path, n=12, spacing=0.1, seed=3):
    """Images stamped ``spacing`` s apart, received OFFSET later with seeded jitter; one image with an earlier
    stamp, one with a zero stamp, and Float64 messages (no header) in between. Returns the stamps."""
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    t = ts.types
    rng = np.random.default_rng(seed)
    w = BagWriter(path, 'mcap', sync=False)
    w.open()
    img = w.add_connection('/clock_test/image', 'sensor_msgs/msg/Image', typestore=ts)
    num = w.add_connection('/clock_test/value', 'std_msgs/msg/Float64', typestore=ts)
    stamps = []
    for k in range(n):
        stamp = T0 + int(k * spacing * S)
        if k == 5:
            stamp = T0 + int(2.5 * spacing * S)      # out of order: must not take the clock back
        if k == 7:
            stamp = 0                                # unset header: must not move the clock
        stamps.append(stamp)
        msg = t['sensor_msgs/msg/Image'](
            header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec=stamp // S, nanosec=stamp % S),
                                            frame_id='s'),
            height=1, width=4, encoding='mono8', is_bigendian=0, step=4, data=np.zeros(4, np.uint8))
        log = T0 + OFFSET + int(k * spacing * S) + int(rng.integers(0, 20_000_000))
        w.write(img, log, ts.serialize_cdr(msg, 'sensor_msgs/msg/Image'))
        w.write(num, log + int(spacing * S / 2), ts.serialize_cdr(t['std_msgs/msg/Float64'](data=float(k)),
                                                                  'std_msgs/msg/Float64'))
    w.close()
    return stamps


def replay_process(*args):
    return subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.bag_replay', *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def finish(proc, timeout=60):
    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise


@pytest.mark.ros
def test_clock_is_the_stamps_monotonic_per_pass_and_fine_grained(tmp_path, ros):
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image
    stamps = stamped_bag(tmp_path / 'bag')
    reliable = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    clocks, images = [], []
    subs = [ros.node.create_subscription(Clock, '/clock', lambda m: clocks.append(m.clock.sec * S + m.clock.nanosec),
                                         reliable),
            ros.node.create_subscription(Image, '/clock_test/image', images.append, reliable)]
    try:
        proc = replay_process(tmp_path / 'bag', '--clock', '--repeat', '2', '--wait-for', '/clock_test/image')
        _, err = finish(proc)
        assert proc.returncode == 0, err
        ros.wait(lambda: len(images) >= 2 * len(stamps), 20.0, 'the replayed images')
        ros.wait(lambda: clocks and clocks[-1] == max(stamps), 20.0, 'the last clock')
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)
    valid = sorted({s for s in stamps if s})
    # Stamps, never receive times; within [first stamp, last stamp].
    assert all(valid[0] <= c <= valid[-1] for c in clocks), (min(clocks), max(clocks), valid[0], valid[-1])
    # Back exactly once: at the start of the second pass, to the first stamp.
    backs = [i for i in range(1, len(clocks)) if clocks[i] < clocks[i - 1]]
    assert len(backs) == 1 and clocks[backs[0]] == valid[0], backs
    for part in (clocks[:backs[0]], clocks[backs[0]:]):
        # Every in-order stamp is published as it is; the earlier and the zero stamp never appear.
        in_order = [s for k, s in enumerate(stamps) if s and k != 5]
        assert set(in_order) <= set(part)
        assert stamps[5] not in part and 0 not in part
        # Between the stamps the clock takes values of its own (it advances at the rate, capped).
        assert set(part) - set(in_order)


@pytest.mark.ros
def test_no_clock_unless_asked_and_refused_beside_another_clock(tmp_path, ros):
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image
    stamped_bag(tmp_path / 'bag', n=4)
    reliable = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    clocks, images = [], []
    subs = [ros.node.create_subscription(Clock, '/clock', clocks.append, reliable),
            ros.node.create_subscription(Image, '/clock_test/image', images.append, reliable)]
    try:
        proc = replay_process(tmp_path / 'bag', '--fast', '--wait-for', '/clock_test/image')
        _, err = finish(proc)
        assert proc.returncode == 0, err
        ros.wait(lambda: len(images) >= 4, 20.0, 'the replayed images')
        assert clocks == []
        other = ros.node.create_publisher(Clock, '/clock', 10)
        try:
            proc = replay_process(tmp_path / 'bag', '--clock', '--fast')
            _, err = finish(proc)
        finally:
            ros.node.destroy_publisher(other)
        assert proc.returncode == EXIT_CLOCK_TAKEN, err
        assert 'another node publishes /clock already' in err and 'Traceback' not in err
        assert len(images) == 4 and clocks == []
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)


@pytest.mark.parametrize('what', ['missing', 'empty-folder'])
def test_a_bag_that_is_not_there_is_a_clear_error(tmp_path, what):
    bag = tmp_path / 'bag'
    if what == 'empty-folder':
        bag.mkdir()
    proc = replay_process(bag)
    _, err = finish(proc)
    assert proc.returncode == EXIT_UNREADABLE and 'Traceback' not in err, err
    assert ('does not exist' if what == 'missing' else 'holds no MCAP or sqlite3 file') in err

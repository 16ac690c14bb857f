"""``bag_replay``: publish a rosbag2's serialized messages again, through rclpy.

Messages go out as recorded (CDR bytes, never deserialised), on publishers offering the recorded
QoS, with their original spacing scaled by ``--rate``, or with ``--fast`` as fast as the
subscribers acknowledge them (each message waits for all acknowledgements before the next, so a
pipeline sees every message in order). ``--loop`` plays again and again, ``--repeat N`` plays N
times. Before it exits, the replayer waits (up to 5 s per topic) until reliable subscribers have
acknowledged every message, so a slow reader still gets the end of the bag.
A bag its recorder did not close (killed, power cut, full disk) is played up to the last complete
chunk of each file, with a warning saying how far it goes; split bags are played file after file.

Clock model (``--clock``; ``/clock`` is published only on request). The replay clock is the
replayed messages' own header stamps: a message whose type has a ``std_msgs/Header`` sets the clock
to its stamp, published just before the message, so a ``use_sim_time`` node never receives a
message stamped after its clock; a message without a header (or with a zero stamp) does not move
it. Within one pass the clock never goes back (an earlier stamp leaves it where it is); a loop or
``--repeat`` starts a new pass, where it may jump back, which ``use_sim_time`` nodes treat as a new
recording. Between two messages it advances at the replay rate from the last published stamp and
never beyond the stamp of the next message that has one (with ``--fast`` it holds between
messages), and it is published at least every 10 ms of wall time while replaying. With ``--clock``
the replayer refuses to start (exit code 3) when another node already publishes ``/clock``: two
clocks would make every ``use_sim_time`` node jump between them.

Start condition. ``--wait-for TOPIC ...`` starts once each of these topics has a subscriber and
every node of the graph that publishes its state (the package's processing nodes and ``sonar_stack``:
``NODE/status``, :mod:`sonar_tracking.ros.status`) takes input, i.e. none says ``starting`` (a
node still loading its kernels would miss the first messages), then waits up to 2 s more for
every subscriber the graph shows on those topics to be matched. ``--wait-ready [NODE ...]`` waits
for the state of the nodes named (fully qualified, ``/active_detector``), or with no name of every
node of the graph that publishes one, also without ``--wait-for``. Both wait ``--wait-timeout``
seconds in all.

Exit codes: 0 = replayed; 1 = the bag cannot be read (no such path, as a recorder killed before it
created its folder leaves it; an empty folder; not a bag), or a ``--wait-for`` topic got no
subscriber or a node still said ``starting`` after ``--wait-timeout``; 2 = bad arguments; 3 =
``--clock`` refused: another node publishes ``/clock``.
"""
from __future__ import annotations

import argparse
import collections
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

__all__ = ['main', 'ReplayClock', 'header_stamp', 'EXIT_OK', 'EXIT_UNREADABLE', 'EXIT_USAGE', 'EXIT_CLOCK_TAKEN']

EXIT_OK, EXIT_UNREADABLE, EXIT_USAGE, EXIT_CLOCK_TAKEN = 0, 1, 2, 3
#: Longest wall time between two ``/clock`` messages while replaying [s] (published twice as often).
CLOCK_PERIOD = 0.01
#: How long ``--clock`` looks for another ``/clock`` publisher before it starts [s] (DDS discovery).
CLOCK_DISCOVERY = 3.0
#: Messages (and bytes) read ahead to find the next stamp the clock must not pass.
LOOKAHEAD_MESSAGES, LOOKAHEAD_BYTES = 64, 16 << 20


def header_stamp(data: bytes) -> int | None:
    """The header stamp [ns] of a CDR message whose first field is a ``std_msgs/Header``; None when the
    bytes are too short or the stamp is zero or negative (a header nobody filled in)."""
    if len(data) < 12:
        return None
    order = 'little' if data[1] & 1 else 'big'
    sec = int.from_bytes(data[4:8], order, signed=True)
    nanosec = int.from_bytes(data[8:12], order)
    ns = sec * 1_000_000_000 + nanosec
    return ns if ns > 0 and nanosec < 1_000_000_000 else None


def stamp_reader(cls) -> Callable[[bytes], int | None] | None:
    """How to get the header stamp from the CDR bytes of a message class: by offset when the header is
    its first field (every stamped message of ROS), by deserialising when it is another top-level
    field; None when the type has no ``std_msgs/Header`` field."""
    fields = list(cls.get_fields_and_field_types().items())
    headers = [name for name, kind in fields if kind == 'std_msgs/Header']
    if not headers:
        return None
    if fields[0][0] == headers[0]:
        return header_stamp
    name = headers[0]

    def by_deserialising(data: bytes) -> int | None:
        from rclpy.serialization import deserialize_message
        try:
            st = getattr(deserialize_message(data, cls), name).stamp
        except Exception:  # noqa: BLE001 - a message that does not deserialise has no stamp to give
            return None
        ns = int(st.sec) * 1_000_000_000 + int(st.nanosec)
        return ns if ns > 0 else None
    return by_deserialising


class ReplayClock:
    """The replay clock of the module docstring, on an explicit wall clock (so it is testable alone).

    :meth:`message` is called just before a stamped message is published, :meth:`at` between
    messages; both return the clock to publish (None before the pass's first stamped message).
    ``rate`` is the replay rate (None with ``--fast``: the clock holds between messages).
    """

    def __init__(self, rate: float | None) -> None:
        self.rate = rate
        self.new_pass()

    def new_pass(self) -> None:
        """Start a pass: the clock has no value until the pass's first stamped message (it may go back)."""
        self.value: int | None = None
        self.base = 0                # clock and wall time at the last stamped message
        self.base_wall = 0.0
        self.limit: int | None = None   # the next stamp: never passed

    def message(self, stamp: int, wall: float, next_stamp: int | None) -> int:
        """A message stamped ``stamp`` goes out at ``wall``; ``next_stamp`` is the next stamped
        message's (None: unknown, the clock holds until then). Returns the clock to publish first."""
        self.value = stamp if self.value is None else max(self.value, stamp)
        self.base, self.base_wall, self.limit = self.value, wall, next_stamp
        return self.value

    def at(self, wall: float) -> int | None:
        """The clock at ``wall`` between messages: advanced at the rate, capped at the next stamp."""
        if self.value is None or self.rate is None or self.limit is None:
            return self.value
        ahead = self.base + int((wall - self.base_wall) * self.rate * 1e9)
        self.value = max(self.value, min(ahead, self.limit))
        return self.value


class _ClockThread:
    """Publishes the replay clock every :data:`CLOCK_PERIOD` / 2 from a thread, and at each stamped
    message from the replaying thread (one lock: the published values never go back in a pass)."""

    def __init__(self, clock: ReplayClock, publish: Callable[[int], None]) -> None:
        self.clock, self.publish = clock, publish
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name='replay_clock', daemon=True)
        self.thread.start()

    def _run(self) -> None:
        due = time.monotonic()
        while not self.stop.is_set():
            with self.lock:
                value = self.clock.at(time.monotonic())
                if value is not None:
                    self.publish(value)
            due = max(due + CLOCK_PERIOD / 2, time.monotonic())
            self.stop.wait(due - time.monotonic())

    def message(self, stamp: int, next_stamp: int | None) -> None:
        with self.lock:
            self.publish(self.clock.message(stamp, time.monotonic(), next_stamp))

    def new_pass(self) -> None:
        with self.lock:
            self.clock.new_pass()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2.0)


def _with_stamps(messages: Iterator, stamp_of: dict[str, Callable[[bytes], int | None] | None]) -> Iterator:
    """``(message, its stamp, the next stamp after it)`` for each message, reading ahead at most
    :data:`LOOKAHEAD_MESSAGES` messages and :data:`LOOKAHEAD_BYTES` bytes for the next stamp."""
    ahead: collections.deque = collections.deque()
    size = 0
    done = False

    def pull() -> bool:
        nonlocal size, done
        if done:
            return False
        msg = next(messages, None)
        if msg is None:
            done = True
            return False
        fn = stamp_of.get(msg.topic)
        ahead.append((msg, fn(msg.data) if fn is not None else None))
        size += len(msg.data)
        return True
    while ahead or pull():
        msg, stamp = ahead.popleft()
        size -= len(msg.data)
        following = None
        if stamp is not None:
            i = 0
            while following is None:
                if i == len(ahead) and (len(ahead) >= LOOKAHEAD_MESSAGES or size >= LOOKAHEAD_BYTES or not pull()):
                    break
                following = ahead[i][1]
                i += 1
        yield msg, stamp, following


def _other_clock(node, stop: threading.Event) -> bool:
    """Whether another node publishes ``/clock``, looked for during :data:`CLOCK_DISCOVERY` seconds."""
    from sonar_tracking.ros.qos import CLOCK_TOPIC
    deadline = time.monotonic() + CLOCK_DISCOVERY
    while not stop.is_set():
        if node.count_publishers(CLOCK_TOPIC) > 0:
            return True
        if time.monotonic() >= deadline:
            return False
        stop.wait(0.02)
    return False


#: How long an automatic readiness wait looks at the graph before it trusts the set of nodes it found [s].
READY_DISCOVERY = 0.5
#: How long the replay waits, after the start condition, for every subscriber the graph shows on a
#: ``--wait-for`` topic to be matched (one with a QoS that never matches is not waited for longer) [s].
MATCH_WAIT = 2.0


def _wait_ready(node, names: list[str] | None, deadline: float, stop: threading.Event, log) -> bool:
    """Wait until none of the nodes ``names`` (None: every node of the graph that publishes a state)
    says ``starting``; False (logged) at ``deadline``."""
    import rclpy

    from sonar_tracking.ros.status import StatusWatch
    watch = StatusWatch(node, names)
    earliest = time.monotonic() + (READY_DISCOVERY if names is None else 0.0)
    said = None
    try:
        while not stop.is_set():
            if watch.auto:
                watch.discover()
            rclpy.spin_once(node, timeout_sec=0.02)
            waiting = watch.waiting()
            now = time.monotonic()
            if not waiting and now >= earliest:
                if watch.states():
                    log.info('every node takes input: ' + ', '.join(f'{n} ({s})' for n, s in
                                                                     sorted(watch.states().items())))
                return True
            if waiting and waiting != said:
                said = waiting
                log.info('waiting for nodes to take input: ' + ', '.join(waiting))
            if now > deadline:
                log.error('still not taking input at the end of --wait-timeout: ' + ', '.join(waiting))
                return False
        return True
    finally:
        watch.close()


def _wait_matched(node, publishers: dict, topics: list[str], stop: threading.Event) -> None:
    """Wait up to :data:`MATCH_WAIT` for every subscriber the graph shows on ``topics`` to be matched."""
    until = time.monotonic() + MATCH_WAIT
    chosen = [(name, publishers[name]) for name in topics if name in publishers]
    while not stop.is_set() and time.monotonic() < until:
        if all(pub.get_subscription_count() >= node.count_subscribers(name) for name, pub in chosen):
            return
        time.sleep(0.02)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``bag_replay``."""
    parser = argparse.ArgumentParser(prog='bag_replay', description=__doc__.split('\n\n')[0],
                                     epilog='Exit codes: 0 replayed, 1 bag unreadable, or no subscriber or a node '
                                            'still starting in time, 2 bad arguments, 3 --clock refused (another '
                                            'node publishes /clock).')
    parser.add_argument('bag', type=Path, help='bag directory (or .mcap file)')
    pace = parser.add_mutually_exclusive_group()
    pace.add_argument('--rate', type=float, default=1.0, help='speed factor (default 1.0 = as recorded)')
    pace.add_argument('--fast', action='store_true', help='as fast as the subscribers take the messages')
    parser.add_argument('--topics', nargs='+', default=None, help='replay only these topics')
    parser.add_argument('--loop', action='store_true', help='play again and again until interrupted')
    parser.add_argument('--repeat', type=int, default=1, help='play N times (default 1)')
    parser.add_argument('--clock', action='store_true',
                        help='publish /clock from the replayed messages\' header stamps (see the clock model above); '
                             'refused when another node publishes /clock')
    parser.add_argument('--wait-for', nargs='+', default=[], metavar='TOPIC',
                        help='start once each of these topics has a subscriber and no node of the graph says it is '
                             'starting (NODE/status)')
    parser.add_argument('--wait-ready', nargs='*', default=None, metavar='NODE',
                        help='start once none of these nodes (/active_detector; none named: every node with a '
                             'NODE/status topic) says it is starting')
    parser.add_argument('--wait-timeout', type=float, default=60.0,
                        help='longest wait for --wait-for and --wait-ready in all [s] (default 60)')
    args, ros_args = parser.parse_known_args(argv)
    if not 0 < args.rate < float('inf') or args.repeat < 1:
        print('error: --rate must be > 0 and finite, --repeat >= 1', file=sys.stderr)
        return EXIT_USAGE

    from sonar_tracking.io.bags import TruncatedBagWarning, bag_state, bag_topics, read_bag
    if not args.bag.exists():
        print(f'error: {args.bag} does not exist (a recorder killed before it created its bag folder leaves '
              f'none)', file=sys.stderr)
        return EXIT_UNREADABLE
    if args.bag.is_dir() and not any(f.exists() for f in bag_state(args.bag).files):
        print(f'error: {args.bag} is not a bag: it holds no MCAP or sqlite3 file', file=sys.stderr)
        return EXIT_UNREADABLE
    try:
        topics = {t.name: t for t in bag_topics(args.bag)}
    except Exception as exc:  # noqa: BLE001 - any reader failure is reported the same way
        print(f'error: cannot read {args.bag}: {exc}', file=sys.stderr)
        return EXIT_UNREADABLE
    chosen = [t for t in topics if args.topics is None or t in args.topics]
    missing = sorted(set(args.topics or []) - set(topics))
    if missing:
        print(f'warning: topics not in the bag: {missing}', file=sys.stderr)

    from sonar_tracking.ros.qos import CLOCK_TOPIC, offered_profile
    from sonar_tracking.ros.runtime import exit_if_teardown_hangs, prepare_process
    prepare_process()
    import rclpy
    from rclpy.duration import Duration
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock

    from sonar_tracking.msgs import ns_to_stamp, rclpy_types

    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bag_replay')
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *a: stop.set())
    signal.signal(signal.SIGTERM, lambda *a: stop.set())
    log = node.get_logger()
    if args.clock and _other_clock(node, stop):
        print(f'error: another node publishes {CLOCK_TOPIC} already; bag_replay --clock would be a second clock '
              f'(stop that publisher, or replay without --clock)', file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()
        return EXIT_CLOCK_TAKEN
    publishers = {}
    stamp_of: dict[str, Callable[[bytes], int | None] | None] = {}
    for name in chosen:
        t = topics[name]
        try:
            cls = rclpy_types().cls(t.msgtype)
            publishers[name] = node.create_publisher(cls, name, offered_profile(t.qos))
        except (ImportError, AttributeError, ValueError) as exc:
            log.warning(f'{name}: type {t.msgtype} not importable ({exc}); skipped')
            continue
        stamp_of[name] = stamp_reader(cls) if args.clock else None

    deadline = time.monotonic() + args.wait_timeout
    for name in args.wait_for:
        pub = publishers.get(name)
        while pub is not None and pub.get_subscription_count() == 0 and not stop.is_set():
            if time.monotonic() > deadline:
                log.error(f'no subscriber on {name} after {args.wait_timeout:g} s')
                node.destroy_node()
                rclpy.try_shutdown()
                return EXIT_UNREADABLE
            time.sleep(0.02)
    if (args.wait_for or args.wait_ready is not None) and not stop.is_set():
        names = ['/' + n.lstrip('/') for n in args.wait_ready] if args.wait_ready else None
        if not _wait_ready(node, names, deadline, stop, log):
            node.destroy_node()
            rclpy.try_shutdown()
            return EXIT_UNREADABLE
        _wait_matched(node, publishers, args.wait_for, stop)

    clock = None
    if args.clock:
        clock_pub = node.create_publisher(Clock, CLOCK_TOPIC, 10)
        clock = _ClockThread(ReplayClock(None if args.fast else args.rate),
                             lambda ns: clock_pub.publish(Clock(clock=ns_to_stamp(ns))))

    sent = 0
    passes = 0
    status = EXIT_OK
    ack = Duration(seconds=5.0)
    try:
        while not stop.is_set() and (args.loop or passes < args.repeat):
            passes += 1
            if clock is not None:
                clock.new_pass()
            t_bag0 = t_wall0 = None
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter('always', TruncatedBagWarning)
                for msg, stamp, following in _with_stamps(read_bag(args.bag, list(publishers)), stamp_of):
                    if stop.is_set():
                        break
                    for w in caught:
                        log.warning(str(w.message))
                    caught.clear()
                    if not args.fast:
                        if t_bag0 is None:
                            t_bag0, t_wall0 = msg.timestamp, time.monotonic()
                        due = t_wall0 + (msg.timestamp - t_bag0) / 1e9 / args.rate
                        while not stop.is_set():
                            now = time.monotonic()
                            if now >= due:
                                break
                            time.sleep(min(0.02, due - now))
                    if clock is not None and stamp is not None:
                        clock.message(stamp, following)
                    pub = publishers[msg.topic]
                    pub.publish(msg.data)
                    sent += 1
                    if args.fast:
                        pub.wait_for_all_acked(ack)
                for w in caught:
                    log.warning(str(w.message))
        if not stop.is_set():   # the last messages reach reliable readers before the writers go
            for name, pub in publishers.items():
                if not pub.wait_for_all_acked(ack):
                    log.warning(f'{name}: not every subscriber acknowledged the last messages within 5 s')
    except Exception as exc:  # noqa: BLE001 - a file damaged past what the reader recovers ends the replay
        print(f'error: reading {args.bag} failed after {sent} messages: {exc}', file=sys.stderr)
        status = EXIT_UNREADABLE
    finally:
        if clock is not None:
            clock.close()
        log.info(f'replayed {sent} messages in {passes} pass(es)')
        exit_if_teardown_hangs(status)
        node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == '__main__':
    sys.exit(main())

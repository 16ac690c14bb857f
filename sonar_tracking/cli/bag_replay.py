"""``bag_replay``: publish a rosbag2's serialized messages again, through rclpy.

Messages go out as recorded (CDR bytes, never deserialised), on publishers offering the recorded
QoS, with their original spacing scaled by ``--rate``, or with ``--fast`` as fast as the
subscribers acknowledge them (each message waits for all acknowledgements before the next, so a
pipeline sees every message in order). ``--clock`` publishes ``/clock`` with the bag's time for
nodes running with ``use_sim_time``. ``--loop`` plays again and again (time goes back at every
wrap; the package's nodes treat that as a new recording), ``--repeat N`` plays N times.
Before it exits, the replayer waits (up to 5 s per topic) until reliable subscribers have
acknowledged every message, so a slow reader still gets the end of the bag.
A bag its recorder did not close (killed, power cut, full disk) is played up to the last complete
chunk of each file, with a warning saying how far it goes; split bags are played file after file.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
import warnings
from pathlib import Path

__all__ = ['main']


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``bag_replay``."""
    parser = argparse.ArgumentParser(prog='bag_replay', description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', type=Path, help='bag directory (or .mcap file)')
    pace = parser.add_mutually_exclusive_group()
    pace.add_argument('--rate', type=float, default=1.0, help='speed factor (default 1.0 = as recorded)')
    pace.add_argument('--fast', action='store_true', help='as fast as the subscribers take the messages')
    parser.add_argument('--topics', nargs='+', default=None, help='replay only these topics')
    parser.add_argument('--loop', action='store_true', help='play again and again until interrupted')
    parser.add_argument('--repeat', type=int, default=1, help='play N times (default 1)')
    parser.add_argument('--clock', action='store_true', help='publish /clock with the bag time')
    parser.add_argument('--wait-for', nargs='+', default=[], metavar='TOPIC',
                        help='start once each of these topics has a subscriber')
    parser.add_argument('--wait-timeout', type=float, default=60.0)
    args, ros_args = parser.parse_known_args(argv)
    if args.rate <= 0 or args.repeat < 1:
        print('error: --rate must be > 0 and --repeat >= 1', file=sys.stderr)
        return 2

    from sonar_tracking.io.bags import TruncatedBagWarning, bag_topics, read_bag
    try:
        topics = {t.name: t for t in bag_topics(args.bag)}
    except Exception as exc:  # noqa: BLE001 - any reader failure is reported the same way
        print(f'error: cannot read {args.bag}: {exc}', file=sys.stderr)
        return 1
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
    publishers = {}
    for name in chosen:
        t = topics[name]
        try:
            publishers[name] = node.create_publisher(rclpy_types().cls(t.msgtype), name, offered_profile(t.qos))
        except (ImportError, AttributeError, ValueError) as exc:
            log.warning(f'{name}: type {t.msgtype} not importable ({exc}); skipped')
    clock_pub = node.create_publisher(Clock, CLOCK_TOPIC, 10) if args.clock else None

    deadline = time.monotonic() + args.wait_timeout
    for name in args.wait_for:
        pub = publishers.get(name)
        while pub is not None and pub.get_subscription_count() == 0 and not stop.is_set():
            if time.monotonic() > deadline:
                log.error(f'no subscriber on {name} after {args.wait_timeout:g} s')
                return 1
            time.sleep(0.02)

    def publish_clock(ns: int) -> None:
        if clock_pub is not None:
            clock_pub.publish(Clock(clock=ns_to_stamp(ns)))

    sent = 0
    passes = 0
    ack = Duration(seconds=5.0)
    try:
        while not stop.is_set() and (args.loop or passes < args.repeat):
            passes += 1
            t_bag0 = t_wall0 = None
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter('always', TruncatedBagWarning)
                for msg in read_bag(args.bag, list(publishers)):
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
                            publish_clock(t_bag0 + int((time.monotonic() - t_wall0) * args.rate * 1e9))
                    publish_clock(msg.timestamp)
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
    finally:
        log.info(f'replayed {sent} messages in {passes} pass(es)')
        exit_if_teardown_hangs(0)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

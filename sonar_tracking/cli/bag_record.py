"""``bag_record``: record ROS 2 topics into a rosbag2 (MCAP by default, or sqlite3) that survives crashes.

Subscriptions are raw (the CDR bytes are written as received, never deserialised) with a deep
queue, and match each topic's publishers: reliable unless one of them is best effort, transient
local when all of them are (so latched topics are caught). The publishers' QoS profiles are
recorded as ``offered_qos_profiles``, so a replay offers the same QoS. Messages are stamped with
their receive time (the node clock, so ``use_sim_time`` works). Without topics, every topic that
appears is recorded. Ctrl-C or SIGTERM closes the bag cleanly.

The bag is written by :class:`~sonar_tracking.io.bags.writer.BagWriter`: a flush every
``--flush-interval`` seconds puts everything received on disk (data, then ``metadata.yaml``,
rosbag2 version 9 as ROS 2 Jazzy writes it). ``kill -9`` or a power cut keeps every message
received before the start of the last completed flush, so it loses at most one interval plus the
flush's ``fsync`` time of received messages. The rewrite of ``metadata.yaml`` (atomic, after the
data) is the observable flush signal: its ``message_count`` is on disk. The bag folder appears
complete (built under a hidden name, then renamed): a killed recording opens as it is in rosbags,
the ``mcap`` library, ``bag_replay`` and ``sonar_import``. A full disk (or a file size limit) stops
the recording with a message: the bag keeps everything flushed before and is closed as well as
the space allows. ``--split-size`` / ``--split-duration`` start a new file when the current one
reaches that size or duration, so one damaged file costs only its part. ``bag_record --repair BAG``
makes a bag whose file was torn (a power cut, a disk error) whole for every reader.

The package's own topics (DESIGN §4) have known types, so they are subscribed at once, before any
publisher exists (reliable, volatile): a recorder started first misses nothing of a pipeline started
after it. Their bag connection, with the publishers' QoS, is made at the first message.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

__all__ = ['main', 'BagRecorder']

_EXCLUDED = {'/rosout', '/parameter_events'}

#: Types of the package's topics (DESIGN §4), subscribed before their publishers appear.
PACKAGE_TOPICS = {
    '/sonar/sector': 'sensor_msgs/msg/Image', '/sonar/sector_info': 'sensor_msgs/msg/LaserScan',
    '/sonar/fan': 'sensor_msgs/msg/Image', '/sonar/truth': 'sensor_msgs/msg/PointCloud2',
    '/platform/odometry': 'nav_msgs/msg/Odometry', '/detections': 'sensor_msgs/msg/PointCloud2',
    '/detector/threshold': 'std_msgs/msg/Float64', '/detector/clutter_density': 'std_msgs/msg/Float64',
    '/tracks': 'sensor_msgs/msg/PointCloud2', '/tracks/markers': 'visualization_msgs/msg/MarkerArray',
    '/fls/regions': 'sensor_msgs/msg/PointCloud2', '/fls/image': 'sensor_msgs/msg/Image',
    '/gpf/tracks': 'sensor_msgs/msg/PointCloud2', '/gpf/tracks/markers': 'visualization_msgs/msg/MarkerArray',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray', '/clock': 'rosgraph_msgs/msg/Clock',
}


class BagRecorder:
    """An rclpy node writing subscribed topics into a crash-safe :class:`BagWriter`.

    ``failure`` is set (and nothing more is written) when the storage fails, e.g. the disk is full.
    """

    def __init__(self, node, out: Path, storage: str, topics: list[str], depth: int = 1000, split_size: int = 0,
                 split_duration: float = 0.0, flush_interval: float = 0.5) -> None:
        from rosbags.typesys import Stores, get_typestore

        from sonar_tracking.io.bags import BagWriter
        self.node = node
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.writer = BagWriter(out, storage, split_size=split_size, split_duration=split_duration)
        self.failure = ''
        self.lost = 0                             # messages received after a failure
        self.writer.open()
        self.lock = threading.Lock()
        self.wanted = set(topics)
        self.all = not topics
        self.depth = depth
        self.types: dict[str, str] = {}          # topic -> type, once subscribed
        self.connections: dict[str, object] = {}  # topic -> bag connection, from its first message
        self.counts: dict[str, int] = {}
        self.subscriptions = []
        self.closed = False
        for topic in sorted(self.wanted & set(PACKAGE_TOPICS)):
            self._subscribe(topic, PACKAGE_TOPICS[topic], None)
        self.discover()
        self.timer = node.create_timer(0.5, self.discover)
        self.flush_interval = flush_interval
        self.next_flush = time.monotonic() + flush_interval
        self.flush_timer = node.create_timer(flush_interval, self.flush)

    def discover(self) -> None:
        """Subscribe to wanted topics that now have publishers."""
        from sonar_tracking.ros.qos import qos_from_rclpy
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.types or topic in _EXCLUDED or not (self.all or topic in self.wanted):
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if infos:
                self._subscribe(topic, types[0], [qos_from_rclpy(i.qos_profile) for i in infos])

    def _subscribe(self, topic: str, msgtype: str, offered: list | None) -> None:
        try:
            cls = self._message_class(msgtype)
        except (ImportError, AttributeError, ValueError) as exc:
            self.node.get_logger().warning(f'{topic}: type {msgtype} not importable ({exc}); not recorded')
            self.types[topic] = msgtype
            return
        self.types[topic] = msgtype
        self.counts[topic] = 0
        self.subscriptions.append(self.node.create_subscription(
            cls, topic, lambda data, t=topic: self._write(t, data), self._qos(offered or []), raw=True))
        self.node.get_logger().info(f'recording {topic} [{msgtype}]')

    def _connection(self, topic: str):
        """The bag connection of a topic, made at its first message with its publishers' QoS."""
        from sonar_tracking.ros.qos import qos_from_rclpy
        conn = self.connections.get(topic)
        if conn is None:
            offered = [qos_from_rclpy(i.qos_profile) for i in self.node.get_publishers_info_by_topic(topic)]
            conn = self.connections[topic] = self.writer.add_connection(
                topic, self.types[topic], typestore=self.typestore, offered_qos_profiles=offered)
        return conn

    def _qos(self, offered):
        from sonar_tracking.ros.qos import offered_profile
        return offered_profile(offered, self.depth)

    @staticmethod
    def _message_class(msgtype: str):
        from sonar_tracking.msgs import rclpy_types
        return rclpy_types().cls(msgtype)

    def _write(self, topic: str, data: bytes) -> None:
        from sonar_tracking.io.bags import BagWriteError
        stamp = self.node.get_clock().now().nanoseconds
        with self.lock:
            if self.closed or self.failure:
                self.lost += not self.closed
                return
            try:
                self.writer.write(self._connection(topic), stamp, data)
            except BagWriteError as exc:
                self._fail(exc)
                return
            self.counts[topic] += 1
        if time.monotonic() >= self.next_flush:      # due, even while callbacks queue ahead of the timer
            self.flush()

    def flush(self) -> None:
        """Put everything received so far on disk (timer callback)."""
        from sonar_tracking.io.bags import BagWriteError
        with self.lock:
            if self.closed or self.failure:
                return
            self.next_flush = time.monotonic() + self.flush_interval
            try:
                self.writer.flush()
            except BagWriteError as exc:
                self._fail(exc)

    def _fail(self, exc: Exception) -> None:
        self.failure = str(exc)
        self.lost += 1
        self.node.get_logger().error(f'recording stopped: {exc}')

    def close(self) -> dict[str, int]:
        """Close the bag (summary and metadata.yaml); returns message counts per topic."""
        from sonar_tracking.io.bags import BagWriteError
        with self.lock:
            if not self.closed:
                self.closed = True
                try:
                    self.writer.close()
                except BagWriteError as exc:
                    self.failure = self.failure or str(exc)
                    self.node.get_logger().error(f'the bag could not be closed completely: {exc}')
        return dict(self.counts)


def parse_size(text: str) -> int:
    """Bytes from ``'500M'``, ``'2G'``, ``'100k'`` or a plain number (powers of 1024)."""
    units = {'k': 1 << 10, 'm': 1 << 20, 'g': 1 << 30, 't': 1 << 40}
    t = text.strip().lower().removesuffix('ib').removesuffix('b')
    scale = units.get(t[-1:], 1)
    try:
        value = float(t[:-1] if t[-1:] in units else t) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a size (e.g. 500M, 2G, 1000000)') from None
    if not value >= 0 or value == float('inf'):
        raise argparse.ArgumentTypeError(f'{text!r}: a size must be finite and >= 0')
    return int(value)


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number of seconds') from None
    if not 0 <= value < float('inf'):
        raise argparse.ArgumentTypeError(f'{text!r}: seconds must be finite and >= 0')
    return value


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``bag_record``."""
    parser = argparse.ArgumentParser(prog='bag_record', description=__doc__.split('\n\n')[0])
    parser.add_argument('-o', '--output', type=Path, help='bag directory to create')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    parser.add_argument('--depth', type=int, default=1000, help='subscription queue depth (default 1000)')
    parser.add_argument('--split-size', type=parse_size, default=0, metavar='SIZE',
                        help='start a new file when the current one reaches SIZE (e.g. 500M, 2G; default: never)')
    parser.add_argument('--split-duration', type=_seconds, default=0.0, metavar='SECONDS',
                        help='start a new file after SECONDS of recording in the current one (default: never)')
    parser.add_argument('--flush-interval', type=_seconds, default=0.5, metavar='SECONDS',
                        help='put what was received on disk this often; a crash loses at most that much '
                             '(default 0.5)')
    parser.add_argument('--repair', type=Path, metavar='BAG',
                        help='make a bag left by a killed recorder readable by every reader, then exit')
    parser.add_argument('topics', nargs='*', help='topics to record (default: all that appear)')
    args, ros_args = parser.parse_known_args(argv)
    if args.repair is not None:
        return _repair(args.repair)
    if args.output is None:
        parser.error('-o/--output is required (or --repair BAG)')
    if args.flush_interval <= 0:
        parser.error('--flush-interval must be > 0')
    if args.depth < 1:
        parser.error('--depth must be >= 1')
    if args.output.exists():
        print(f'error: {args.output} exists already; bag_record never overwrites', file=sys.stderr)
        return 2
    # A file size limit (ulimit -f) must end the recording like a full disk, not kill the process.
    if hasattr(signal, 'SIGXFSZ'):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    from sonar_tracking.ros.runtime import prepare_process
    prepare_process()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bag_record')
    from sonar_tracking.io.bags import BagWriteError
    try:
        recorder = BagRecorder(node, args.output, args.storage, args.topics, args.depth, args.split_size,
                               args.split_duration, args.flush_interval)
    except BagWriteError as exc:
        print(f'error: cannot start the bag: {exc}', file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()

    def on_signal(signum, frame):
        stop.set()
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        while not stop.is_set() and not recorder.failure:
            executor.spin_once(timeout_sec=0.1)
        # Take what is already queued before closing.
        for _ in range(200 if not recorder.failure else 0):
            executor.spin_once(timeout_sec=0.0)
    except ExternalShutdownException:
        pass
    finally:
        counts = recorder.close()
        node.destroy_node()
        rclpy.try_shutdown()
    on_disk, first, last = recorder.writer.stats()
    if recorder.failure:
        print(f'bag_record: recording stopped early: {recorder.failure}. {args.output} holds the {on_disk} messages '
              f'flushed before ({(last - first) / 1e9:.2f} s); {sum(counts.values()) - on_disk + recorder.lost} '
              f'received messages are not in it', file=sys.stderr)
    else:
        print(f'bag_record: wrote {on_disk} messages on {len(counts)} topics to {args.output}', file=sys.stderr)
    return 0


def _repair(bag: Path) -> int:
    from sonar_tracking.io.bags import repair
    try:
        done = repair(bag)
    except Exception as exc:  # noqa: BLE001 - whatever stops the repair is reported, not raised
        print(f'error: cannot repair {bag}: {exc}', file=sys.stderr)
        return 1
    for line in done or [f'{bag} was closed by its recorder; nothing to repair']:
        print(f'bag_record --repair: {line}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())

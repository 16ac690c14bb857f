"""``bag_record``: record ROS 2 topics into a rosbag2 (MCAP by default, or sqlite3) with rosbags.

Subscriptions are raw (the CDR bytes are written as received, never deserialised) with a deep
queue, and match each topic's publishers: reliable unless one of them is best effort, transient
local when all of them are (so latched topics are caught). The publishers' QoS profiles are
recorded as ``offered_qos_profiles``, so a replay offers the same QoS. Messages are stamped with
their receive time (the node clock, so ``use_sim_time`` works). The metadata is version 8, which
ROS 2 Jazzy's ``ros2 bag info`` reads. Without topics, every topic that appears is recorded.
Ctrl-C or SIGTERM closes the bag cleanly.

The package's own topics (DESIGN §4) have known types, so they are subscribed at once, before any
publisher exists (reliable, volatile): a recorder started first misses nothing of a pipeline started
after it. Their bag connection, with the publishers' QoS, is made at the first message.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
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
    """An rclpy node writing subscribed topics into a rosbags Writer."""

    def __init__(self, node, out: Path, storage: str, topics: list[str], depth: int = 1000) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
        self.node = node
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.writer = Writer(out, version=8,
                             storage_plugin=StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3)
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

    def discover(self) -> None:
        """Subscribe to wanted topics that now have publishers."""
        from .bags import qos_from_rclpy
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
        from .bags import qos_from_rclpy
        conn = self.connections.get(topic)
        if conn is None:
            offered = [qos_from_rclpy(i.qos_profile) for i in self.node.get_publishers_info_by_topic(topic)]
            conn = self.connections[topic] = self.writer.add_connection(
                topic, self.types[topic], typestore=self.typestore, offered_qos_profiles=offered)
        return conn

    def _qos(self, offered):
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        # Unknown publishers (a package topic subscribed early): reliable and volatile.
        reliable = all(q.reliability.name == 'RELIABLE' for q in offered)
        transient = bool(offered) and all(q.durability.name == 'TRANSIENT_LOCAL' for q in offered)
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=self.depth,
                          reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)

    @staticmethod
    def _message_class(msgtype: str):
        from msg_adapters import rclpy_types
        return rclpy_types().cls(msgtype)

    def _write(self, topic: str, data: bytes) -> None:
        stamp = self.node.get_clock().now().nanoseconds
        with self.lock:
            if self.closed:
                return
            self.writer.write(self._connection(topic), stamp, data)
            self.counts[topic] += 1

    def close(self) -> dict[str, int]:
        """Close the bag (writes metadata.yaml); returns message counts per topic."""
        with self.lock:
            if not self.closed:
                self.closed = True
                self.writer.close()
        return dict(self.counts)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``bag_record``."""
    parser = argparse.ArgumentParser(prog='bag_record', description=__doc__.split('\n\n')[0])
    parser.add_argument('-o', '--output', type=Path, required=True, help='bag directory to create')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    parser.add_argument('--depth', type=int, default=1000, help='subscription queue depth (default 1000)')
    parser.add_argument('topics', nargs='*', help='topics to record (default: all that appear)')
    args, ros_args = parser.parse_known_args(argv)
    if args.output.exists():
        print(f'error: {args.output} exists already; bag_record never overwrites', file=sys.stderr)
        return 2

    from sonar_tracking.ros.runtime import prepare_process
    prepare_process()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bag_record')
    recorder = BagRecorder(node, args.output, args.storage, args.topics, args.depth)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()

    def on_signal(signum, frame):
        stop.set()
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
        # Take what is already queued before closing.
        for _ in range(200):
            executor.spin_once(timeout_sec=0.0)
    except ExternalShutdownException:
        pass
    finally:
        counts = recorder.close()
        node.destroy_node()
        rclpy.try_shutdown()
    total = sum(counts.values())
    print(f'bag_record: wrote {total} messages on {len(counts)} topics to {args.output}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())

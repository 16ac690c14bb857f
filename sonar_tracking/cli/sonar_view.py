"""``sonar_view``: a live view of a pipeline, or of a bag, in a browser on this machine.

Live (default), a node ``sonar_view`` subscribes to the pipeline's topics by RELATIVE names
(``sonar/sector`` + ``sonar/sector_info``, ``platform/odometry``, ``sonar/truth``, ``detections``,
``detector/threshold``, ``detector/clutter_density``, ``tracks``, ``fls/image`` +
``fls/image_info``, ``fls/regions``, ``gpf/tracks``; ``--ros-args -r __ns:=/auv1`` follows a
namespaced pipeline) and logs what arrives (:mod:`sonar_tracking.cli.view.scene`). With
``--bag DIR`` it logs a recorded run instead, on the same ``stamp`` timeline, so the browser
scrubs it in time. The view is Rerun's: the SDK hosts a gRPC server (``--grpc-port``) holding the
recording (up to ``--memory-limit``, oldest data dropped first) and serves its web viewer over
HTTP (``--web-port``), both on 127.0.0.1 only; the address to open is printed as
``view: http://...``. A live view logs only while a viewer is connected to its server
(:func:`viewer_connected`, checked ten times a second). It subscribes at start (so ``sonar_stack``
and the simulator, which wait for their listeners, count it), takes its messages serialized and
drops them while no viewer is connected, and once the pipeline runs unsubscribes until one
connects, so that without a browser it costs the pipeline nothing (``sonar_eval bench view``);
a browser shows the run from the moment it connects. ``--always`` (implied by ``--save``) logs
everything, so a browser opened later sees the run from its start. The record topics are taken
best effort (``--qos``): the view adds no acknowledgements to the pipeline's reliable writers and
never slows them; its bounded queues drop the oldest messages when it falls behind. ``--save FILE.rrd``
also writes the recording to a file (open it later with ``rerun FILE.rrd``); ``--no-serve`` only
writes the file. Rerun is an extra: without it, the program says to run ``make view``.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from urllib.parse import quote

__all__ = ['main', 'viewer_url']

MISSING = ('sonar_view needs the view extra (Rerun, ~170 MB): run `make view` '
           '(or `.venv/bin/pip install -r requirements-view.txt`)')


def viewer_url(web_port: int, grpc_uri: str) -> str:
    """The web viewer's address, told which gRPC server to stream from."""
    return f'http://127.0.0.1:{web_port}/?url={quote(grpc_uri, safe="")}'


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='sonar_view', description=__doc__.split('\n\n')[0])
    p.add_argument('--bag', type=Path, default=None, metavar='DIR', help='show a recorded bag instead of live topics')
    p.add_argument('--ns', default='/', help='namespace of the pipeline in the bag (default /)')
    p.add_argument('--grpc-port', type=int, default=9876, help='port of the recording server (default 9876)')
    p.add_argument('--web-port', type=int, default=9090, help='port of the web viewer (default 9090)')
    p.add_argument('--memory-limit', default='25%', help='recording memory kept by the server (default 25%% of RAM)')
    p.add_argument('--save', type=Path, default=None, metavar='FILE.rrd', help='also write the recording to a file')
    p.add_argument('--no-serve', action='store_true', help='serve nothing (with --save: only write the file)')
    p.add_argument('--fan-px', type=int, default=768, help='longer side of the fan image (default 768 px)')
    p.add_argument('--fan-period', type=float, default=0.5, help='seconds between fan images (default 0.5)')
    p.add_argument('--coding', default='linear_amplitude',
                   help='how sector values code the echo: linear_amplitude (default), linear_power, db, display')
    p.add_argument('--sonar-pose', type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=('X', 'Y', 'YAW'),
                   help='sonar pose in the world when no platform/odometry arrives (default 0 0 0)')
    p.add_argument('--tail', type=int, default=40, help='points per track tail (default 40)')
    p.add_argument('--arrow-seconds', type=float, default=10.0, help='time span of velocity arrows (default 10 s)')
    p.add_argument('--qos', choices=('best_effort', 'reliable'), default='best_effort',
                   help='QoS of the record topics (default best_effort: the view never slows a publisher; '
                   'reliable: every message, for tests). Images are always best effort.')
    p.add_argument('--always', action='store_true',
                   help='log every message, also while no browser is connected (so one opened later shows the '
                   'run from its start); --save implies it')
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``sonar_view``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args = argv[argv.index('--ros-args'):] if '--ros-args' in argv else []
    args = _parser().parse_args(argv[:len(argv) - len(ros_args)])
    try:
        import rerun as rr

        from sonar_tracking.cli.view.scene import SceneLogger, blueprint
    except ImportError:
        print(f'error: {MISSING}', file=sys.stderr)
        return 2
    if args.no_serve and args.save is None:
        print('error: --no-serve without --save would show nothing', file=sys.stderr)
        return 2
    if args.bag is not None and not args.bag.exists():
        print(f'error: no bag at {args.bag}', file=sys.stderr)
        return 2
    rec = rr.RecordingStream('sonar_view')
    sinks = []
    if not args.no_serve:
        try:
            server = rr.GrpcServerSink(bind_ip='127.0.0.1', port=args.grpc_port, server_memory_limit=args.memory_limit)
        except Exception as exc:  # the binding raises its own error types (port in use, bad limit)
            print(f'error: cannot host the recording server on port {args.grpc_port}: {exc}', file=sys.stderr)
            return 2
        sinks.append(server)
    if args.save is not None:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        sinks.append(rr.FileSink(str(args.save)))
    rec.set_sinks(*sinks, default_blueprint=blueprint())
    try:
        scene = SceneLogger(rec, fan_px=args.fan_px, fan_period=args.fan_period, coding=args.coding,
                            sonar_pose=tuple(args.sonar_pose), tail=args.tail, arrow_seconds=args.arrow_seconds)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    url = None
    if not args.no_serve:
        try:
            rr.serve_web_viewer(web_port=args.web_port, open_browser=False, connect_to=server.uri)
        except Exception as exc:
            print(f'error: cannot serve the web viewer on port {args.web_port}: {exc}', file=sys.stderr)
            return 2
        url = viewer_url(args.web_port, server.uri)
    try:
        if args.bag is not None:
            return _show_bag(args, scene, rec, url)
        gate = None if args.always or args.save is not None or args.no_serve else args.grpc_port
        return _show_live(scene, rec, url, ros_args, args.qos, gate)
    finally:
        rec.flush()
        rec.disconnect()


def _summary(scene) -> str:
    text = ', '.join(f'{t} {n}' for t, n in sorted(scene.counts.items())) or 'no messages'
    for topic, n in sorted(scene.errors.items()):
        text += f'; {n} dropped on {topic} (last: {scene.last_error[topic]})'
    return text


def _show_bag(args: argparse.Namespace, scene, rec, url: str | None) -> int:
    from rosbags.typesys import Stores, get_typestore

    from sonar_tracking.cli.view import TOPICS
    from sonar_tracking.io.bags import bag_topics, read_bag
    ns = '/' + args.ns.strip('/') + '/' if args.ns.strip('/') else '/'
    names = {ns + rel: rel for rel in TOPICS}
    topics = {t.name: t.msgtype for t in bag_topics(args.bag) if t.name in names}
    if not topics:
        print(f'error: {args.bag} has none of the topics {sorted(names)}', file=sys.stderr)
        return 1
    store = get_typestore(Stores.ROS2_JAZZY)
    for m in read_bag(args.bag, list(topics)):
        try:
            msg = store.deserialize_cdr(m.data, topics[m.topic])
        except Exception as exc:  # rosbags raises several kinds for corrupt CDR
            scene.errors[m.topic] = scene.errors.get(m.topic, 0) + 1
            scene.last_error[m.topic] = f'cannot deserialize: {exc}'
            continue
        scene.handle(names[m.topic], msg)
    scene.finish()
    rec.flush()
    print(f'[sonar_view] bag {args.bag}: {_summary(scene)}', flush=True)
    if url is None:
        return 0
    print(f'view: {url}', flush=True)
    print('[sonar_view] serving the bag until Ctrl-C', flush=True)
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *a: stop.set())
    signal.signal(signal.SIGTERM, lambda *a: stop.set())
    stop.wait()
    return 0


def viewer_connected(port: int) -> bool:
    """Whether a TCP connection to local ``port`` is established (a viewer streaming from the server).

    Reads ``/proc/net/tcp`` and ``tcp6`` (Linux); elsewhere it answers True, so the view logs always.
    """
    found = False
    for table in ('/proc/net/tcp', '/proc/net/tcp6'):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        found = True
        for line in lines:
            fields = line.split()
            # local address "IP:PORT" in hex, state 01 = ESTABLISHED
            if len(fields) > 3 and fields[3] == '01' and int(fields[1].rsplit(':', 1)[1], 16) == port:
                return True
    return not found


def _show_live(scene, rec, url: str | None, ros_args: list[str], qos: str, gate: int | None) -> int:
    from sonar_tracking.ros.runtime import run_node

    def factory():
        from rclpy.node import Node
        from rclpy.qos import qos_profile_sensor_data
        from rclpy.serialization import deserialize_message

        from sonar_tracking.cli.view import IMAGE_TOPICS, TOPICS
        from sonar_tracking.msgs import rclpy_types
        from sonar_tracking.ros.qos import input_profile

        class ViewNode(Node):
            def __init__(self) -> None:
                super().__init__('sonar_view')
                types = rclpy_types()
                # Record topics by the package's reader rule; best effort never slows a publisher.
                records = input_profile('reliable' if qos == 'reliable' else 'sensor_data', depth=50)
                self.specs = [(topic, types.cls(msgtype), qos_profile_sensor_data if topic in IMAGE_TOPICS
                               else records) for topic, msgtype in TOPICS.items()]
                self.connected = gate is None
                self.running = False  # a message arrived: the pipeline runs (the stack's waits are over)
                self.subs = []
                self._subscribe()
                self.create_timer(10.0, self._report)
                if gate is not None:
                    self.create_timer(0.1, self._check_viewer)
                self.get_logger().info(f'listening in namespace {self.get_namespace()!r} to '
                                       f'{len(self.subs)} topics')
                if url is not None:
                    print(f'view: {url}', flush=True)

            def _subscribe(self) -> None:
                # Raw: a message is only copied until a viewer wants it deserialized.
                self.subs = [self.create_subscription(cls, topic, lambda data, t=topic, c=cls: self._take(t, c, data),
                                                      profile, raw=True) for topic, cls, profile in self.specs]

            def _take(self, topic: str, cls: type, data: bytes) -> None:
                self.running = True
                if self.connected:
                    scene.handle(topic, deserialize_message(data, cls))

            def _check_viewer(self) -> None:
                connected = viewer_connected(gate)
                if connected and not self.subs:
                    self._subscribe()
                if connected != self.connected:
                    self.get_logger().info('a viewer connected: logging' if connected else
                                           'no viewer connected: not logging')
                self.connected = connected
                if not connected and self.subs and self.running:
                    # Once the pipeline runs, no subscription is left to cost it anything.
                    for sub in self.subs:
                        self.destroy_subscription(sub)
                    self.subs = []
                    self.get_logger().info('unsubscribed until a viewer connects')

            def _report(self) -> None:
                self.get_logger().info(_summary(scene))

            def destroy_node(self) -> None:
                scene.finish()
                # The context may be shut down already: print, not rosout.
                print(f'[sonar_view] {_summary(scene)}', flush=True)
                super().destroy_node()

        return ViewNode()

    return run_node(factory, ['sonar_view', *ros_args])


if __name__ == '__main__':
    sys.exit(main())

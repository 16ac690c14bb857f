"""``sonar_view``: a live view of a pipeline, or of a bag, in a browser on this machine.

Live (default), a node ``sonar_view`` subscribes to the pipeline's topics by RELATIVE names
(``sonar/sector`` + ``sonar/sector_info``, ``platform/odometry``, ``sonar/truth``, ``detections``,
``detector/threshold``, ``detector/clutter_density``, ``tracks``, ``fls/image`` +
``fls/image_info``, ``fls/regions``, ``gpf/tracks``; ``--ros-args -r __ns:=/auv1`` follows a
namespaced pipeline) and logs what arrives (:mod:`sonar_tracking.cli.view.scene`). With
``--bag DIR`` it logs a recorded run instead, on the same ``time`` timeline, so the browser
scrubs it in time. The view is Rerun's: the SDK hosts a gRPC server (``--grpc-port``, default 9876)
holding the recording (up to ``--memory-limit``, oldest data dropped first), and Rerun's viewer
program serves its web viewer over HTTP (``--web-port``, default 9090) as a child process
(:mod:`sonar_tracking.cli.view.serve`). Both listen on 127.0.0.1 only, unless ``--bind`` names
another address (``--bind 0.0.0.0``: every interface, for a browser on another machine). A default
port that is taken (another view runs) is replaced by a free one; a port given explicitly that is
taken is an error. The address to open is printed as ``view: http://...``.

What reaches the browser is bounded, since a browser without GPU renders slowly: the recording is
sent in batches every ``--batch`` seconds (default 1; the browser's work grows with the number of
messages it is sent more than with their size: ``sonar_eval bench view.browser``), the messages of
each record topic (detections, tracks, truth, regions, the plotted scalars) at most once per
``--record-period`` of stamp time (default 0.2 s; the newest of a shorter interval is held and logged
only if nothing newer follows within that time, so the end of a run is always there), and the sonar
images at most once per ``--fan-period`` (default 1 s) of stamp time and of wall-clock time.

A live view logs only while a viewer is connected to its server (:func:`viewer_connected`,
checked ten times a second). It subscribes at start (so ``sonar_stack`` and the simulator, which
wait for their listeners, count it), takes its messages serialized and drops them while no viewer
is connected, and once the pipeline runs unsubscribes until one connects, so that without a
browser it costs the pipeline nothing (``sonar_eval bench view``); a browser shows the run from the
moment it connects. ``--always`` (implied by ``--save``; ``sonar_stack --view`` passes it) logs
everything, so a browser opened later sees the run from its start. The record topics are taken
best effort by default (``--qos``): the view adds no acknowledgements to the pipeline's reliable
writers and never slows them; its bounded queues drop the oldest messages when it falls behind
(``sonar_stack --view`` passes ``--qos reliable``, keep-last, so that the recording has every scan).
``--save FILE.rrd`` also writes the recording to a file (open it later with ``rerun FILE.rrd``);
``--no-serve`` only writes the file. Rerun is an extra: without it, the program says to run ``make view``.
"""
from __future__ import annotations

import argparse
import ipaddress
import signal
import sys
import threading
import time
from datetime import timedelta
from pathlib import Path

from sonar_tracking.cli.view.serve import (
    DEFAULT_GRPC_PORT,
    DEFAULT_WEB_PORT,
    ServeError,
    grpc_uri,
    listening,
    pick_port,
    port_free,
    viewer_connected,
    viewer_url,
)

__all__ = ['main', 'viewer_url', 'viewer_connected']

MISSING = ('sonar_view needs the view extra (Rerun, ~170 MB): run `make view` '
           '(or `.venv/bin/pip install -r requirements-view.txt`)')


# Queue of each record topic (tracks, detections, truth; small messages): a stack at rate 0 sends
# a hundred scans a second while a busy view logs slower, and a message that leaves a keep-last
# queue is a hole in the run. 1000 bounds the memory to a few MB per topic.
RECORD_DEPTH = 1000
# A headless browser without GPU keeps up with the records of about five scans a second
# (``sonar_eval bench view.browser_rates``).
RECORD_PERIOD = 0.2


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='sonar_view', description=__doc__.split('\n\n')[0])
    p.add_argument('--bag', type=Path, default=None, metavar='DIR', help='show a recorded bag instead of live topics')
    p.add_argument('--ns', default='/', help='namespace of the pipeline in the bag (default /)')
    p.add_argument('--grpc-port', type=int, default=None,
                   help='port of the recording server (default 9876, or a free one when 9876 is taken)')
    p.add_argument('--web-port', type=int, default=None,
                   help='port of the web viewer (default 9090, or a free one when 9090 is taken)')
    p.add_argument('--bind', default='127.0.0.1', metavar='ADDR',
                   help='address both servers listen on (default 127.0.0.1: this machine only; 0.0.0.0: every '
                   'interface, so a browser on another machine can connect)')
    p.add_argument('--memory-limit', default='25%', help='recording memory kept by the server (default 25%% of RAM)')
    p.add_argument('--save', type=Path, default=None, metavar='FILE.rrd', help='also write the recording to a file')
    p.add_argument('--no-serve', action='store_true', help='serve nothing (with --save: only write the file)')
    p.add_argument('--fan-px', type=int, default=768, help='longer side of the fan image (default 768 px)')
    p.add_argument('--fan-period', type=float, default=1.0,
                   help='seconds between sonar images, of stamp time and (live) of wall-clock time (default 1)')
    p.add_argument('--record-period', type=float, default=RECORD_PERIOD,
                   help='seconds of stamp time between two logged messages of one record topic (detections, '
                   f'tracks, truth, regions, plots; default {RECORD_PERIOD:g}: a 20 Hz imaging sonar logged at 5 Hz, '
                   'so that a browser without GPU keeps up); 0 logs every message')
    p.add_argument('--batch', type=float, default=1.0,
                   help='seconds of logging sent to the browser at once (default 1)')
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
        from sonar_tracking.cli.view.serve import WebViewer
    except ImportError:
        print(f'error: {MISSING}', file=sys.stderr)
        return 2
    if args.no_serve and args.save is None:
        print('error: --no-serve without --save would show nothing', file=sys.stderr)
        return 2
    if args.bag is not None and not args.bag.exists():
        print(f'error: no bag at {args.bag}', file=sys.stderr)
        return 2
    try:
        ipaddress.ip_address(args.bind)
    except ValueError:
        print(f'error: --bind {args.bind}: not an IP address (127.0.0.1, 0.0.0.0, ::1, ...)', file=sys.stderr)
        return 2
    if not args.batch > 0:
        print('error: --batch must be > 0 seconds', file=sys.stderr)
        return 2
    rec = rr.RecordingStream('sonar_view', batcher_config=rr.ChunkBatcherConfig(
        flush_tick=timedelta(seconds=args.batch)))
    web = url = grpc_port = None
    try:
        if args.no_serve:
            args.save.parent.mkdir(parents=True, exist_ok=True)
            rec.set_sinks(rr.FileSink(str(args.save)), default_blueprint=blueprint())
        else:
            try:
                grpc_port = _serve_recording(rr, rec, args, blueprint())
                web = _serve_viewer(WebViewer, args, grpc_port)
            except ServeError as exc:
                print(f'error: {exc}', file=sys.stderr)
                return 2
            url = viewer_url(args.bind, web.port, grpc_uri(args.bind, grpc_port))
        try:
            scene = SceneLogger(rec, fan_px=args.fan_px, fan_period=args.fan_period, coding=args.coding,
                                sonar_pose=tuple(args.sonar_pose), tail=args.tail, arrow_seconds=args.arrow_seconds,
                                clock=None if args.bag is not None else time.monotonic,
                                record_period=args.record_period)
        except ValueError as exc:
            print(f'error: {exc}', file=sys.stderr)
            return 2
        if args.bag is not None:
            return _show_bag(args, scene, rec, url)
        gate = None if args.always or args.save is not None or args.no_serve else grpc_port
        return _show_live(scene, rec, url, ros_args, args.qos, gate, args.fan_period)
    finally:
        try:
            rec.flush()
            rec.disconnect()
        except RuntimeError:  # a recording server that never started has nothing to flush
            pass
        if web is not None:
            web.stop()


def _serve_recording(rr, rec, args: argparse.Namespace, layout) -> int:
    """Start the recording server (and the file sink) on ``--bind``; returns its port. The SDK does not
    report a port that is taken, so the port is checked to be ours; a default one is then replaced."""
    if args.grpc_port is not None and not port_free(args.bind, args.grpc_port):
        raise ServeError(f'cannot host the recording server on {args.bind}:{args.grpc_port}: the port is taken')
    tried: set[int] = set()
    for _ in range(5):
        port = args.grpc_port if args.grpc_port is not None else pick_port(args.bind, DEFAULT_GRPC_PORT, tried)
        tried.add(port)
        try:
            sinks = [rr.GrpcServerSink(bind_ip=args.bind, port=port, server_memory_limit=args.memory_limit)]
        except Exception as exc:  # the binding raises its own error types (a bad memory limit)
            raise ServeError(f'cannot host the recording server on {args.bind}:{port}: {exc}') from None
        if args.save is not None:
            args.save.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(args.save)))
        rec.set_sinks(*sinks, default_blueprint=layout)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            if any(p == port for _, p in listening()):
                return port
            time.sleep(0.02)
        if args.grpc_port is not None:
            break
    raise ServeError(f'cannot host the recording server on {args.bind}:{port}: the port is taken')


def _serve_viewer(web_viewer, args: argparse.Namespace, grpc_port: int):
    """Start the web viewer on ``--bind``; a default port that turns out taken is replaced."""
    if args.web_port is not None and not port_free(args.bind, args.web_port):
        raise ServeError(f'cannot serve the web viewer on {args.bind}:{args.web_port}: the port is taken')
    tried = {grpc_port}
    error = None
    for _ in range(5):
        port = args.web_port if args.web_port is not None else pick_port(args.bind, DEFAULT_WEB_PORT, tried)
        tried.add(port)
        try:
            return web_viewer(args.bind, port, grpc_uri(args.bind, grpc_port))
        except ServeError as exc:
            error = exc
            if args.web_port is not None:
                break
    raise ServeError(str(error))


def _summary(scene) -> str:
    text = ', '.join(f'{t} {n}' for t, n in sorted(scene.counts.items())) or 'no messages'
    for topic, n in sorted(scene.errors.items()):
        text += f'; {n} dropped on {topic} (last: {scene.last_error[topic]})'
    if scene.held:
        text += f'; {scene.held} records left out for newer ones (--record-period {scene.record_period:g} s)'
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


def _show_live(scene, rec, url: str | None, ros_args: list[str], qos: str, gate: int | None,
               image_period: float) -> int:
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
                records = input_profile('reliable' if qos == 'reliable' else 'sensor_data', depth=RECORD_DEPTH)
                self.specs = [(topic, types.cls(msgtype), qos_profile_sensor_data if topic in IMAGE_TOPICS
                               else records) for topic, msgtype in TOPICS.items()]
                self.connected = gate is None
                self.running = False  # a message arrived: the pipeline runs (the stack's waits are over)
                self.subs = []
                self._reported = ''
                self._subscribe()
                self.create_timer(10.0, self._report)
                # Sonar images held back by the period go out once it is over, also after the last sector.
                self.create_timer(max(0.1, 0.5 * image_period), self._images)
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

            def _images(self) -> None:
                if self.connected:
                    scene.flush_images()

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
                text = _summary(scene)
                if text != self._reported:  # an idle view (a finished run kept for the browser) stays quiet
                    self._reported = text
                    self.get_logger().info(text)

            def destroy_node(self) -> None:
                scene.finish()
                # The context may be shut down already: print, not rosout.
                print(f'[sonar_view] {_summary(scene)}', flush=True)
                super().destroy_node()

        return ViewNode()

    return run_node(factory, ['sonar_view', *ros_args])


if __name__ == '__main__':
    sys.exit(main())

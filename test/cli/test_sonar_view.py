"""sonar_view: messages -> Rerun entities in the right place, bags, no extra -> `make view`, and a
headless Chromium loading the view of a running stack (the screenshot is kept in out/)."""
from __future__ import annotations

import base64
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking import process
from sonar_tracking.core.sector import SectorGeometry

OUT = Path(__file__).resolve().parents[2] / 'out' / 'test_sonar_view'
SONAR = (100.0, 50.0, math.pi / 2)  # the sonar looks along +y of the world


def rrd_columns(path: Path) -> dict[str, dict[str, list]]:
    """entity -> component column -> [(stamp_ns, value), ...] in stamp order, from an .rrd file."""
    import pyarrow as pa
    from rerun.chunk import RrdReader
    out: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        names = batch.schema.names
        stamps = (batch.column('stamp').cast(pa.int64()).to_pylist() if 'stamp' in names
                  else [None] * batch.num_rows)
        for name in names:
            if name in ('rerun.controls.RowId', 'log_time', 'stamp'):
                continue
            out[chunk.entity_path][name].extend(zip(stamps, batch.column(name).to_pylist()))
    for cols in out.values():
        for rows in cols.values():
            rows.sort(key=lambda r: -1 if r[0] is None else r[0])
    return out


def geometry() -> SectorGeometry:
    return SectorGeometry(angle_min=-0.3, angle_increment=0.01, n_beams=61, range_min=10.0, range_max=109.0,
                          n_bins=100, ping_period=0.01, scan_time=1.0)


def scan_messages(types, k: int) -> list[tuple[str, object]]:
    """One scan of every topic the view reads, stamped k seconds; the sonar sees one bright cell at
    range 60 m, bearing 0 (world (100, 110)); track 7 is confirmed at (100 + k, 110), track 8 tentative."""
    stamp = (10 + k) * 10**9
    amp = np.full((100, 61), 0.1, np.float32)
    amp[50, 30] = 100.0
    geom = geometry()
    det = np.zeros(2, ma.DETECTION_DTYPE)
    det['x'], det['y'] = [100.0, 90.0], [110.0, 80.0]
    tracks = np.zeros(2, ma.TRACK_DTYPE)
    tracks['track_id'], tracks['confirmed'] = [7, 8], [1, 0]
    tracks['x'], tracks['y'], tracks['vx'] = [100.0 + k, 60.0], [110.0, 60.0], [1.0, 0.0]
    tracks['cov_xx'], tracks['cov_yy'] = 4.0, 1.0
    truth = np.zeros(1, ma.TRUTH_DTYPE)
    truth['target_id'], truth['x'], truth['y'] = 1, 100.0 + k, 111.0
    regions = np.zeros(1, ma.REGION_DTYPE)
    regions['region_id'], regions['x'], regions['y'] = 3, 95.0, 105.0
    gpf = np.zeros(1, ma.GPF_TRACK_DTYPE)
    gpf['track_id'], gpf['confirmed'], gpf['x'], gpf['y'], gpf['cov_xx'], gpf['cov_yy'] = 2, 1, 96.0, 104.0, 1.0, 1.0
    from sonar_tracking.core.fls.grid import ImageGrid
    from sonar_tracking.msgs.map_info import grid_to_map_info
    fls = np.full((20, 30), 0.1, np.float32)
    fls[2, 25] = 50.0  # pixel centre (25.5, 2.5) m from the grid origin (80, 90): world (105.5, 92.5)
    grid = ImageGrid(resolution=1.0, width=30, height=20, origin_x=80.0, origin_y=90.0)
    odom = ma.pose_to_odometry(*SONAR, stamp_ns=stamp, frame_id='world', types=types)
    f64 = 'std_msgs/msg/Float64'
    return [
        ('sonar/sector', ma.array_to_image(amp, stamp_ns=stamp, types=types)),
        ('sonar/sector_info', ma.geometry_to_scan(geom, stamp_ns=stamp, types=types)),
        ('sonar/truth', ma.array_to_cloud(truth, stamp_ns=stamp, types=types)),
        ('platform/odometry', odom),
        ('detections', ma.array_to_cloud(det, stamp_ns=stamp, types=types)),
        ('detector/threshold', types.new(f64, data=3.0 + 0.1 * k)),
        ('detector/clutter_density', types.new(f64, data=1e-4)),
        ('tracks', ma.array_to_cloud(tracks, stamp_ns=stamp, types=types)),
        ('fls/image_info', grid_to_map_info(grid, stamp, types=types)),
        ('fls/image', ma.array_to_image(fls, stamp_ns=stamp, frame_id='world', types=types)),
        ('fls/regions', ma.array_to_cloud(regions, stamp_ns=stamp, types=types)),
        ('gpf/tracks', ma.array_to_cloud(gpf, stamp_ns=stamp, types=types)),
    ]


def decode_image(blob) -> np.ndarray:
    import cv2
    return cv2.imdecode(np.frombuffer(bytes(blob), np.uint8), cv2.IMREAD_GRAYSCALE)


def brightest_in_map(cols: dict, image_col: str) -> tuple[float, float]:
    """Map coordinates (u, v) of the brightest pixel of the last image of an entity, through its transform."""
    img = decode_image(cols[image_col][-1][1][0])
    row, col = np.unravel_index(np.argmax(img), img.shape)
    t = np.array(cols['Transform3D:translation'][-1][1][0][:2])
    scale = cols['Transform3D:scale'][-1][1][0][0]
    rotation = cols.get('Transform3D:rotation_axis_angle')
    angle = rotation[-1][1][0]['angle'] if rotation else 0.0
    c, s = math.cos(angle), math.sin(angle)
    p = scale * np.array([col + 0.5, row + 0.5])
    return tuple(t + np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]]))


def test_scene_puts_every_topic_in_place_on_the_map(tmp_path, rosbags_types):
    import rerun as rr

    from sonar_tracking.cli.view.scene import SceneLogger
    rec = rr.RecordingStream('test_scene')
    path = tmp_path / 'scene.rrd'
    rec.set_sinks(rr.FileSink(str(path)))
    scene = SceneLogger(rec, fan_px=200, fan_period=0.0)
    for k in range(3):
        for topic, msg in scan_messages(rosbags_types, k):
            assert scene.handle(topic, msg), (topic, scene.last_error)
    scene.finish()
    rec.flush()
    rec.disconnect()
    assert scene.errors == {}
    cols = rrd_columns(path)
    # One row per message on the map and the plots, at the message stamps.
    for entity in ('/map/detections', '/map/tracks/confirmed/points', '/map/tracks/tentative/points',
                   '/map/truth/points', '/map/regions', '/map/gpf/confirmed/points'):
        assert [s for s, _ in cols[entity]['Points2D:positions']] == [(10 + k) * 10**9 for k in range(3)], entity
    assert [v[0] for _, v in cols['/plots/threshold']['Scalars:scalars']] == pytest.approx([3.0, 3.1, 3.2])
    assert [v for _, v in cols['/plots/confirmed/imm_ipda']['Scalars:scalars']] == [[1.0]] * 3
    # Map coordinates are (x, -y): x to the right, y up.
    assert cols['/map/detections']['Points2D:positions'][-1][1] == [[100.0, -110.0], [90.0, -80.0]]
    assert cols['/map/tracks/confirmed/points']['Points2D:labels'][-1][1] == ['T7']
    assert cols['/map/tracks/confirmed/points']['Points2D:positions'][-1][1] == [[102.0, -110.0]]
    assert cols['/map/tracks/tentative/points']['Points2D:positions'][-1][1] == [[60.0, -60.0]]
    assert 'Points2D:labels' not in cols['/map/tracks/tentative/points'] or \
        not cols['/map/tracks/tentative/points']['Points2D:labels'][-1][1]
    # The tail holds the three positions of track 7; the velocity arrow spans arrow_seconds (10 s).
    assert cols['/map/tracks/confirmed/tails']['LineStrips2D:strips'][-1][1] == [[[100.0, -110.0], [101.0, -110.0],
                                                                                 [102.0, -110.0]]]
    assert cols['/map/tracks/confirmed/velocity']['Arrows2D:vectors'][-1][1] == [[10.0, -0.0]]
    # 2-sigma ellipse of cov diag(4, 1): half axes 4 m along x and 2 m along y.
    ellipse = np.array(cols['/map/tracks/confirmed/covariance']['LineStrips2D:strips'][-1][1][0])
    assert np.ptp(ellipse[:, 0]) == pytest.approx(8.0, abs=0.1) and np.ptp(ellipse[:, 1]) == pytest.approx(4.0, abs=0.1)
    # The bright sonar cell (range 60 m straight ahead of a sonar at (100, 50) facing +y) lands at (100, 110).
    u, v = brightest_in_map(cols['/map/fan'], 'EncodedImage:blob')
    assert (u, v) == pytest.approx((100.0, -110.0), abs=2.0)
    # The FLS image's bright pixel at world (105.5, 92.5).
    u, v = brightest_in_map(cols['/map/fls_image'], 'EncodedImage:blob')
    assert (u, v) == pytest.approx((105.5, -92.5), abs=0.8)


def test_bad_messages_are_dropped_and_counted(tmp_path, rosbags_types):
    import rerun as rr

    from sonar_tracking.cli.view.scene import SceneLogger
    rec = rr.RecordingStream('test_bad')
    rec.set_sinks(rr.FileSink(str(tmp_path / 'bad.rrd')))
    scene = SceneLogger(rec)
    wrong = ma.array_to_cloud(np.zeros(2, ma.TRUTH_DTYPE), types=rosbags_types)  # truth on the tracks topic
    assert not scene.handle('tracks', wrong)
    assert not scene.handle('detector/threshold', rosbags_types.new('std_msgs/msg/Float64', data=float('nan')))
    bad_scan = ma.geometry_to_scan(geometry(), stamp_ns=5, types=rosbags_types)
    image = ma.array_to_image(np.zeros((100, 7), np.float32), stamp_ns=5, types=rosbags_types)  # 7 beams, not 61
    scene.handle('sonar/sector_info', bad_scan)
    assert not scene.handle('sonar/sector', image)
    assert scene.errors == {'tracks': 1, 'detector/threshold': 1, 'sonar/sector': 1}
    assert 'cov_xx' in scene.last_error['tracks'] and '7 beams' in scene.last_error['sonar/sector']
    for topic, msg in scan_messages(rosbags_types, 0):  # and it keeps working
        assert scene.handle(topic, msg), topic
    rec.disconnect()


def write_bag(path: Path, types, scans: int) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer

    from sonar_tracking.cli.view.scene import TOPICS
    store = types.typestore
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {t: writer.add_connection('/' + t, m, typestore=store) for t, m in TOPICS.items()}
        for k in range(scans):
            for topic, msg in scan_messages(types, k):
                writer.write(conns[topic], (10 + k) * 10**9, store.serialize_cdr(msg, TOPICS[topic]))


def test_a_bag_becomes_a_recording(tmp_path, rosbags_types):
    write_bag(tmp_path / 'bag', rosbags_types, 4)
    rrd = tmp_path / 'bag.rrd'
    r = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.sonar_view', '--bag', str(tmp_path / 'bag'),
                        '--save', str(rrd), '--no-serve'], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert 'tracks 4' in r.stdout and 'dropped' not in r.stdout
    cols = rrd_columns(rrd)
    assert len(cols['/map/tracks/confirmed/points']['Points2D:positions']) == 4
    assert len(cols['/map/gpf/confirmed/points']['Points2D:positions']) == 4
    assert len(cols['/plots/clutter_density']['Scalars:scalars']) == 4
    # A namespace that is not in the bag is refused with the topics it looked for.
    r = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.sonar_view', '--bag', str(tmp_path / 'bag'),
                        '--ns', '/auv1', '--no-serve', '--save', str(rrd)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and '/auv1/tracks' in r.stderr


def test_without_the_extra_it_says_make_view():
    code = ('import sys; sys.modules["rerun"] = None\n'
            'from sonar_tracking.cli.sonar_view import main; sys.exit(main([]))')
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and '`make view`' in r.stderr


def test_viewer_connected_sees_established_connections_to_its_port():
    from sonar_tracking.cli.sonar_view import viewer_connected
    with socket.socket() as server:
        server.bind(('127.0.0.1', 0))
        server.listen()
        port = server.getsockname()[1]
        assert not viewer_connected(port)  # listening is not connected
        client = socket.create_connection(('127.0.0.1', port))
        conn, _ = server.accept()
        assert viewer_connected(port)
        client.close()
        conn.close()
        assert not viewer_connected(port)


# -- the browser ------------------------------------------------------------------------------------

class Chromium:
    """Headless Chromium driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``)."""

    def __init__(self, width: int = 1600, height: int = 1000) -> None:
        to_child, self._w = os.pipe()
        self._r, from_child = os.pipe()
        self.profile = tempfile.mkdtemp(prefix='sonar_view_chromium_')
        args = [shutil.which('chromium'), '--headless=new', '--remote-debugging-pipe', '--no-sandbox',
                '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-first-run',
                '--disable-background-networking', f'--user-data-dir={self.profile}',
                f'--window-size={width},{height}', 'about:blank']

        def fds() -> None:
            os.dup2(to_child, 3)
            os.dup2(from_child, 4)
        self.proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=process.child_dies_with_parent(then=fds),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        os.close(to_child)
        os.close(from_child)
        self._id, self._buf, self.events = 0, b'', []
        target = self.call('Target.createTarget', url='about:blank')['targetId']
        self.session = self.call('Target.attachToTarget', targetId=target, flatten=True)['sessionId']
        self.size = (width, height)

    def call(self, method: str, session: str | None = None, **params) -> dict:
        self._id += 1
        msg = {'id': self._id, 'method': method, 'params': params}
        if session:
            msg['sessionId'] = session
        os.write(self._w, json.dumps(msg).encode() + b'\0')
        while True:
            while b'\0' not in self._buf:
                chunk = os.read(self._r, 1 << 20)
                if not chunk:
                    raise RuntimeError('chromium closed the DevTools pipe')
                self._buf += chunk
            raw, self._buf = self._buf.split(b'\0', 1)
            reply = json.loads(raw)
            if reply.get('id') == self._id:
                if 'error' in reply:
                    raise RuntimeError(f'{method}: {reply["error"]}')
                return reply['result']
            self.events.append(reply)

    def page(self, method: str, **params) -> dict:
        return self.call(method, self.session, **params)

    def screenshot(self) -> bytes:
        return base64.b64decode(self.page('Page.captureScreenshot', format='png')['data'])

    def received_bytes(self, url_part: str) -> int:
        """Bytes the page received on requests whose URL contains ``url_part`` (DevTools Network events)."""
        ids = {e['params']['requestId'] for e in self.events
               if e.get('method') == 'Network.requestWillBeSent' and url_part in e['params']['request']['url']}
        return sum(e['params']['dataLength'] for e in self.events
                   if e.get('method') == 'Network.dataReceived' and e['params']['requestId'] in ids)

    def close(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._w)
        os.close(self._r)
        shutil.rmtree(self.profile, ignore_errors=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def colour_pixels(png: bytes, rgb: tuple[int, int, int], box: tuple[int, int, int, int], tol: int = 40) -> int:
    """Pixels of ``png`` within ``tol`` of colour ``rgb`` inside ``box = (x0, y0, x1, y1)``."""
    import cv2
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[box[1]:box[3], box[0]:box[2], ::-1]
    return int((np.abs(img.astype(int) - np.array(rgb)).max(axis=2) <= tol).sum())


MAP = (0, 40, 960, 960)  # the map view in a 1600 x 1000 page

STACK = '''
on_exit: stop
nodes:
  imm_ipda_tracker: {params_file: package:imm_ipda.yaml}
  active_detector:
    params_file: package:active_detector.yaml
    parameters: {esc.density_source: best_track, esc.desired_clutter_density: 7.52e-5}
  seaking_sim:
    params_file: package:sim_harbour.yaml
    parameters: {rate: 4.0, duration: %d.0, wait_for_subscribers: 1}
    wait_for: {/sonar/sector: 1, /sonar/sector_info: 1, /detections: 1}
'''


@pytest.mark.ros
@pytest.mark.slow
def test_the_browser_shows_a_running_stack(tmp_path):
    if shutil.which('chromium') is None:
        pytest.skip('Debian\'s chromium is not installed (`make view-deps` installs it)')
    import rerun  # noqa: F401  (the extra must be installed: `make view-deps`)
    scans = 40
    (tmp_path / 'stack.yaml').write_text(STACK % scans)
    grpc, web, rrd = free_port(), free_port(), tmp_path / 'view.rrd'
    OUT.mkdir(parents=True, exist_ok=True)
    log = (OUT / 'stack.log').open('w')
    stack = subprocess.Popen(
        [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', '--config', str(tmp_path / 'stack.yaml'),
         '--view', f'--grpc-port {grpc} --web-port {web} --save {rrd} --qos reliable'],
        stdout=log, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        preexec_fn=process.child_dies_with_parent())
    browser = None
    try:
        url = wait_for_line(stack, OUT / 'stack.log', r'\[sonar_view\] view: (\S+)').group(1)
        browser = Chromium()
        browser.page('Network.enable')
        browser.page('Page.enable')
        browser.page('Emulation.setDeviceMetricsOverride', width=1600, height=1000, deviceScaleFactor=1, mobile=False)
        browser.page('Page.navigate', url=url)
        finished = wait_for_line(stack, OUT / 'stack.log', r'finished after (\d+) sectors')
        assert int(finished.group(1)) == scans
        # Wait until the page draws the run: the fan (dark pixels), detections (orange) on the map, the
        # threshold curve (red).
        deadline, shot, missing = time.monotonic() + 180, b'', ['everything']
        while missing and time.monotonic() < deadline:
            shot = browser.screenshot()
            missing = [what for what, colour, box, n in (
                ('the fan', (10, 10, 10), MAP, 100_000), ('detections', (255, 160, 0), MAP, 50),
                ('the threshold curve', (230, 60, 60), (960, 40, 1600, 300), 50))
                if colour_pixels(shot, colour, box) < n]
            time.sleep(1.0)
        (OUT / 'screenshot.png').write_bytes(shot)
        assert not missing, f'not drawn: {missing} (see {OUT / "screenshot.png"})'
        received = browser.received_bytes(f':{grpc}/')
    finally:
        if stack.poll() is None:
            os.killpg(stack.pid, signal.SIGINT)
            stack.wait(30)
        log.close()
        if browser is not None:
            browser.close()
    # The recording the page streamed: one row per scan of every record topic, the fan at least once.
    cols = rrd_columns(rrd)
    for entity, column in (('/map/detections', 'Points2D:positions'), ('/map/truth/points', 'Points2D:positions'),
                           ('/map/tracks/tentative/points', 'Points2D:positions'),
                           ('/plots/clutter_density', 'Scalars:scalars')):
        assert len(cols[entity][column]) == scans, entity
    assert len(cols['/plots/threshold']['Scalars:scalars']) >= scans  # plus the initial one
    assert len(cols['/map/fan']['EncodedImage:blob']) >= 1
    # The page itself received that stream from the view's server: at least half of the file's bytes.
    assert received > 0.5 * rrd.stat().st_size, (received, rrd.stat().st_size)


def wait_for_line(proc: subprocess.Popen, log: Path, pattern: str, timeout: float = 180.0) -> re.Match:
    """Wait until the stack's log matches ``pattern`` (fails if the stack exits first)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        m = re.search(pattern, log.read_text())
        if m:
            return m
        if proc.poll() is not None:
            break
        time.sleep(0.2)
    raise AssertionError(f'no {pattern!r} in the stack output:\n{log.read_text()[-3000:]}')

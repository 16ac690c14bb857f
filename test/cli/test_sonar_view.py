"""sonar_view's scene: messages -> Rerun entities in the right place, on a timeline of seconds since the
start; a layout with the panels of what arrived; the polar picture, grid, scale bar, legend and per-track
details; sonar images bounded in time; bags; no extra -> `make view`. The browser tests are in
test_view_browser.py, the servers' ports and addresses in test_view_serve.py."""
from __future__ import annotations

import math
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import SectorGeometry

SONAR = (100.0, 50.0, math.pi / 2)  # the sonar looks along +y of the world
rr = pytest.importorskip('rerun')  # the view extra (`make view-deps` installs it)


def rrd_columns(path: Path) -> dict[str, dict[str, list]]:
    from sonar_tracking.cli.view.browser import rrd_columns as columns
    return columns(path)


def geometry() -> SectorGeometry:
    return SectorGeometry(angle_min=-0.3, angle_increment=0.01, n_beams=61, range_min=10.0, range_max=109.0,
                          n_bins=100, ping_period=0.01, scan_time=1.0)


def scan_messages(types, k: int) -> list[tuple[str, object]]:
    """One scan of every topic the view reads, stamped 10 + k seconds; the sonar sees one bright cell at
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
    tracks['existence'], tracks['mode_cv'], tracks['mode_ccw'], tracks['mode_cw'] = [0.9, 0.3], 0.6, 0.3, 0.1
    tracks['cov_xx'], tracks['cov_yy'] = 4.0, 1.0
    truth = np.zeros(1, ma.TRUTH_DTYPE)
    truth['target_id'], truth['x'], truth['y'] = 1, 100.0 + k, 111.0
    regions = np.zeros(1, ma.REGION_DTYPE)
    regions['region_id'], regions['x'], regions['y'] = 3, 95.0, 105.0
    gpf = np.zeros(1, ma.GPF_TRACK_DTYPE)
    gpf['track_id'], gpf['confirmed'], gpf['x'], gpf['y'], gpf['cov_xx'], gpf['cov_yy'] = 2, 1, 96.0, 104.0, 1.0, 1.0
    gpf['fusion'] = 1
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


FLS_TOPICS = {'sonar/sector', 'sonar/sector_info', 'sonar/truth', 'platform/odometry', 'fls/image_info',
              'fls/image', 'fls/regions', 'gpf/tracks'}


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


def log_scans(path: Path, types, scans: int, topics: set[str] | None = None, **kw):
    """Log ``scans`` scans (only ``topics`` if given) to an .rrd file; returns the scene logger."""
    from sonar_tracking.cli.view.scene import SceneLogger
    rec = rr.RecordingStream('test_scene')
    rec.set_sinks(rr.FileSink(str(path)))
    scene = SceneLogger(rec, fan_px=200, fan_period=0.0, **kw)
    for k in range(scans):
        for topic, msg in scan_messages(types, k):
            if topics is None or topic in topics:
                assert scene.handle(topic, msg), (topic, scene.last_error)
    scene.finish()
    rec.flush()
    rec.disconnect()
    return scene


def test_scene_puts_every_topic_in_place_on_the_map(tmp_path, rosbags_types):
    path = tmp_path / 'scene.rrd'
    scene = log_scans(path, rosbags_types, 3)
    assert scene.errors == {}
    cols = rrd_columns(path)
    # One row per message on the map and the plots, at seconds since the first stamp (10 s): 0, 1, 2 s.
    for entity in ('/map/detections', '/map/tracks/confirmed/points', '/map/tracks/tentative/points',
                   '/map/truth/points', '/map/regions', '/map/gpf/confirmed/points'):
        assert [s for s, _ in cols[entity]['Points2D:positions']] == [k * 10**9 for k in range(3)], entity
    assert [v[0] for _, v in cols['/plots/threshold']['Scalars:scalars']] == pytest.approx([3.0, 3.1, 3.2])
    assert [v for _, v in cols['/plots/confirmed/imm_ipda']['Scalars:scalars']] == [[1.0]] * 3
    # The run's first stamp is a property of the recording.
    assert cols['/__properties/run']['first_stamp_ns'][-1][1] == [10 * 10**9]
    assert cols['/__properties/run']['first_stamp'][-1][1] == ['1970-01-01T00:00:10.000000000Z']
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


def test_selected_tracks_show_their_details_and_region_labels_leave_track_ids_visible(tmp_path, rosbags_types):
    path = tmp_path / 'details.rrd'
    log_scans(path, rosbags_types, 2)
    cols = rrd_columns(path)
    confirmed = cols['/map/tracks/confirmed/points']
    assert confirmed['track_id'][-1][1] == [7]
    assert confirmed['existence'][-1][1] == pytest.approx([0.9])
    assert [confirmed[m][-1][1][0] for m in ('mode_cv', 'mode_ccw', 'mode_cw')] == pytest.approx([0.6, 0.3, 0.1])
    assert confirmed['speed_m_s'][-1][1] == pytest.approx([1.0])
    assert cols['/map/tracks/tentative/points']['existence'][-1][1] == pytest.approx([0.3])
    gpf = cols['/map/gpf/confirmed/points']
    assert gpf['fusion'][-1][1] == ['WF (weighted sum)'] and gpf['Points2D:labels'][-1][1] == ['T2']
    # Regions keep their id for hover and selection but draw no label over the track ids.
    regions = cols['/map/regions']
    assert regions['Points2D:show_labels'][-1][1] == [False] and regions['region_id'][-1][1] == [3]
    assert confirmed['Points2D:show_labels'][-1][1] == [True]


def test_the_layout_has_panels_only_for_what_arrived(tmp_path, rosbags_types):
    from sonar_tracking.cli.view.browser import panel_names
    from sonar_tracking.cli.view.scene import PANELS
    log_scans(tmp_path / 'fls.rrd', rosbags_types, 2, topics=FLS_TOPICS)
    fls = set(panel_names(tmp_path / 'fls.rrd'))
    assert fls == {PANELS[k] for k in ('map', 'legend', 'polar', 'confirmed', 'counts')}
    log_scans(tmp_path / 'all.rrd', rosbags_types, 2)
    assert set(panel_names(tmp_path / 'all.rrd')) == set(PANELS.values())
    # The legend names the colours of what is present, in the colours drawn.
    cols = rrd_columns(tmp_path / 'fls.rrd')
    labels = cols['/legend']['Points2D:labels'][-1][1]
    assert any('GPF track, confirmed' in t for t in labels) and any('FLS region' in t for t in labels)
    assert not any('IMM-IPDA' in t or t == 'detection' for t in labels)


def test_the_map_has_a_grid_and_a_scale_bar(tmp_path, rosbags_types):
    from sonar_tracking.cli.view.scene import grid_spacing
    assert [grid_spacing(e) for e in (8.0, 110.0, 1700.0, 0.3)] == pytest.approx([1.0, 20.0, 500.0, 0.05])
    log_scans(tmp_path / 'grid.rrd', rosbags_types, 1)
    cols = rrd_columns(tmp_path / 'grid.rrd')
    strips = [np.array(s) for s in cols['/map/grid']['LineStrips2D:strips'][-1][1]]
    xs = sorted({round(float(s[0, 0]), 6) for s in strips if s[0, 0] == s[1, 0]})  # vertical lines
    step = np.diff(xs)
    assert len(xs) >= 3 and np.allclose(step, step[0])
    bar = np.array(cols['/map/scale']['LineStrips2D:strips'][-1][1][0])
    assert np.ptp(bar[:, 0]) == pytest.approx(step[0])
    assert cols['/map/scale']['LineStrips2D:labels'][-1][1] == [f'{step[0]:g} m (grid {step[0]:g} m)']


def test_the_polar_picture_puts_sectors_side_by_side_port_left_far_range_up():
    from sonar_tracking.cli.view.scene import PolarScan
    scan = PolarScan()
    # A scanning head: sectors of 10 beams of 1 deg, from -20 deg up to +19 deg.
    step = math.radians(1.0)
    for first in range(-20, 20, 10):
        geom = SectorGeometry(angle_min=math.radians(first), angle_increment=step, n_beams=10, range_min=1.0,
                              range_max=50.0, n_bins=50)
        values = np.full((50, 10), 1.0, np.float32)
        if first == 10:
            values[40, 5] = 1000.0  # range 41 m, bearing +15 deg
        assert scan.paint(values, geom)  # a new picture, then one that grows
    assert scan.image.shape == (50, 40)
    assert not scan.paint(values, geom)  # the same bearings again: same picture
    row, col = np.unravel_index(np.nanargmax(scan.image), scan.image.shape)
    assert row == 49 - 40  # far range on top
    assert math.degrees(scan.top - col * scan.step) == pytest.approx(15.0)  # port (positive bearing) left
    assert col == 4
    # Few beams are stretched to a wide picture; the ticks label its edges in those pixels.
    assert scan.stretch == 2 and scan.picture(30.0).shape == (50, 80)
    positions, labels = scan.ticks()
    assert labels[:3] == ['+19.0 deg', '+0.0 deg', '-20.0 deg'] and labels[3] == '50 m'
    assert positions[2][0] == pytest.approx(79.0)
    # A new range scale starts the picture anew; more beams than MAX_COLS are thinned.
    wide = SectorGeometry(angle_min=-1.0, angle_increment=2.0 / 2999, n_beams=3000, range_min=1.0, range_max=9.0,
                          n_bins=2000)
    assert scan.paint(np.ones((2000, 3000), np.float32), wide)
    assert scan.image.shape == (500, 1000)


def test_sonar_images_at_most_once_per_period_of_stamp_and_clock_time(tmp_path, rosbags_types):
    from sonar_tracking.cli.view.scene import SceneLogger
    rec = rr.RecordingStream('test_period')
    rec.set_sinks(rr.FileSink(str(tmp_path / 'period.rrd')))
    now = [100.0]
    scene = SceneLogger(rec, fan_px=64, fan_period=0.5, clock=lambda: now[0])
    sector = [(t, m) for k in range(10) for t, m in scan_messages(rosbags_types, k)
              if t in ('sonar/sector', 'sonar/sector_info', 'platform/odometry')]
    for topic, msg in sector:  # ten sectors 1 s of stamp time apart, all at one instant of the clock
        assert scene.handle(topic, msg)
    assert scene.images_logged == 1
    assert not scene.flush_images()  # the period has not passed on the clock
    now[0] += 0.6
    assert scene.flush_images() and scene.images_logged == 2  # the latest sector's picture
    assert not scene.flush_images()  # nothing new
    rec.disconnect()
    cols = rrd_columns(tmp_path / 'period.rrd')
    assert [t for t, _ in cols['/map/fan']['EncodedImage:blob']] == [0, 9 * 10**9]
    assert [t for t, _ in cols['/sector/polar']['EncodedImage:blob']] == [0, 9 * 10**9]


def test_records_at_most_once_per_record_period_and_the_last_always(tmp_path, rosbags_types):
    # Scans 1 s apart, a period of 1.5 s: 10 s logged, 11 held then left out for 12, 12 logged, 13 left
    # out, 14 logged, 15 held and logged at the end of the run.
    path = tmp_path / 'thin.rrd'
    scene = log_scans(path, rosbags_types, 6, record_period=1.5)
    cols = rrd_columns(path)
    for entity in ('/map/detections', '/map/tracks/confirmed/points', '/map/truth/points', '/map/regions',
                   '/map/gpf/confirmed/points'):
        assert [t for t, _ in cols[entity]['Points2D:positions']] == [0, 2 * 10**9, 4 * 10**9, 5 * 10**9], entity
    assert [v[0] for _, v in cols['/plots/threshold']['Scalars:scalars']] == pytest.approx([3.0, 3.2, 3.4, 3.5])
    assert len(cols['/map/fan']['EncodedImage:blob']) == 6  # the images keep their own period (0 here)
    from sonar_tracking.cli.view import RECORD_TOPICS
    records = {t for t, _ in scan_messages(rosbags_types, 0)} & RECORD_TOPICS
    assert scene.held == 2 * len(records) and scene.counts['tracks'] == 4


def test_a_held_record_is_logged_once_its_topic_went_quiet_for_a_period(tmp_path, rosbags_types):
    from sonar_tracking.cli.view.scene import SceneLogger
    rec = rr.RecordingStream('test_quiet')
    rec.set_sinks(rr.FileSink(str(tmp_path / 'quiet.rrd')))
    now = [100.0]
    scene = SceneLogger(rec, fan_px=64, record_period=1.5, clock=lambda: now[0])
    tracks = [[m for t, m in scan_messages(rosbags_types, k) if t == 'tracks'][0] for k in range(2)]
    assert scene.handle('tracks', tracks[0]) and scene.handle('tracks', tracks[1])
    assert scene.counts['tracks'] == 1           # the second (1 s later in stamp time) is held
    now[0] += 1.0
    scene.flush_images()
    assert scene.counts['tracks'] == 1           # not yet a period of the clock without a newer one
    now[0] += 0.6
    scene.flush_images()
    assert scene.counts['tracks'] == 2 and scene.held == 0
    rec.disconnect()


def test_frames_over_the_same_cells_are_painted_only_when_a_picture_is_due(tmp_path, rosbags_types):
    from dataclasses import replace

    from sonar_tracking.cli.view.scene import SceneLogger

    def sectors(scene, k: int, geom) -> None:
        stamp = (10 + k) * 10**9
        amp = np.full((100, 61), 0.1 + k, np.float32)
        for topic, msg in (('sonar/sector', ma.array_to_image(amp, stamp_ns=stamp, types=rosbags_types)),
                           ('sonar/sector_info', ma.geometry_to_scan(geom, stamp_ns=stamp, types=rosbags_types)),
                           ('platform/odometry', ma.pose_to_odometry(*SONAR, stamp_ns=stamp, frame_id='world',
                                                                    types=rosbags_types))):
            assert scene.handle(topic, msg)

    rec = rr.RecordingStream('test_frames')
    rec.set_sinks(rr.FileSink(str(tmp_path / 'frames.rrd')))
    # An imaging sonar: every frame over the same cells, 1 s apart, a picture every 2 s.
    frames = SceneLogger(rec, fan_px=64, fan_period=2.0)
    for k in range(5):
        sectors(frames, k, geometry())
    frames.finish()
    assert frames.frames_skipped == 2 and frames.images_logged == 3   # 11 s and 13 s never painted
    assert np.nanmax(frames._canvas.image) == pytest.approx(4.1)   # the last frame is the picture
    # A scanning sonar: each sector another part of the fan, every one painted.
    sweep = SceneLogger(rec, fan_px=64, fan_period=2.0)
    for k in range(5):
        sectors(sweep, k, replace(geometry(), angle_min=-0.3 + 0.61 * (k % 2)))
    sweep.finish()
    assert sweep.frames_skipped == 0
    rec.disconnect()


def test_bad_messages_are_dropped_and_counted(tmp_path, rosbags_types):
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


def _varint(n: int) -> bytes:
    out = b''
    while True:
        out += bytes([n & 0x7F | (0x80 if n > 0x7F else 0)])
        n >>= 7
        if not n:
            return out


def _field(number: int, value) -> bytes:
    if isinstance(value, int):
        return _varint(number << 3) + _varint(value)
    return _varint(number << 3 | 2) + _varint(len(value)) + value


def test_the_timeline_range_is_read_from_the_viewer_state():
    """The page's newest row comes from the viewer's state (Rerun 0.41's GetStateResponse: field 3 the
    recording, its field 2 a timeline with name {1: name} and range {1: min, 2: max})."""
    from sonar_tracking.cli.view.browser import timeline_range

    def timeline(name: str, lo: int, hi: int) -> bytes:
        return _field(2, _field(1, _field(1, name.encode())) + _field(2, 3) + _field(3, _field(1, lo) + _field(2, hi)))
    recording = (_field(1, b'Recording:sonar_view:1') + timeline('time', 5, 9)
                 + timeline('log_time', 1_795_820_728_570_401_707, 1_795_820_735_877_934_713))
    state = _field(1, b'about:recording') + _field(3, recording) + _field(6, b'0.41.0')
    lo, hi = timeline_range(state, 'log_time')
    assert lo == pytest.approx(1_795_820_728.570_401_7) and hi == pytest.approx(1_795_820_735.877_934_7)
    assert timeline_range(state, 'time') == pytest.approx((5e-9, 9e-9))
    assert timeline_range(state, 'frame') == (None, None)
    assert timeline_range(_field(1, b'about:recording'), 'log_time') == (None, None)   # no recording yet


def test_the_page_lag_is_the_age_of_the_oldest_row_it_lacks():
    from sonar_tracking.cli.view.browser import page_lags
    logged = [10.0, 11.0, 12.0, 15.0]
    polls = [(9.5, None), (10.5, None), (12.8, 10.0), (13.0, 12.0), (14.9, 12.0), (15.4, 12.0), (16.0, 15.0)]
    # nothing logged yet; row 10 missing 0.5 s; rows 11 and 12 missing, 11 for 1.8 s; all held; nothing newer
    # logged (a quiet sensor is no lag); row 15 missing 0.4 s; all held
    assert page_lags(polls, logged) == pytest.approx([0.0, 0.5, 1.8, 0.0, 0.0, 0.4, 0.0])

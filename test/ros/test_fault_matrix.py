"""The fault matrix: bad input against every node, in process. For each case the node stays alive,
says why (a counted drop with a logged reason), keeps its state, and its next good output is
identical to that of a node that never saw the bad input. Sector consumers give the same verdict."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.msgs.map_info import grid_to_map_info

pytestmark = pytest.mark.ros

GEOM = SectorGeometry(angle_min=-0.4, angle_increment=0.01, n_beams=81, range_min=1.0, range_max=30.0, n_bins=150)


def amplitudes(seed: int, target=(90, 40)) -> np.ndarray:
    a = np.random.default_rng(seed).exponential(1.0, GEOM.shape).astype(np.float32)
    a[target[0] - 1:target[0] + 2, target[1] - 1:target[1] + 2] = 40.0
    return a


def sector(t: float, amp=None, encoding='32FC1', **scan):
    amp = amplitudes(int(t * 10)) if amp is None else amp
    ns = int(round(t * 1e9))
    img = ma.array_to_image(amp.astype(ma.ENCODING_DTYPES.get(encoding, np.float32)) if encoding in ma.ENCODING_DTYPES
                            else amp, encoding if encoding in ma.ENCODING_DTYPES else '32FC1', stamp_ns=ns,
                            frame_id='sonar')
    if encoding not in ma.ENCODING_DTYPES:
        img.encoding = encoding
    shaped = np.shape(amp) == GEOM.shape and np.isfinite(amp).all()
    info = ma.geometry_to_scan(GEOM, amplitudes=np.asarray(amp, float) if shaped else None, stamp_ns=ns,
                               frame_id='sonar')
    for k, v in scan.items():
        setattr(info, k, v)
    return img, info


def _short(t):
    img, info = sector(t)
    img.data = bytes(img.data)[:100]
    return img, info


def _with(t, values):
    amp = amplitudes(int(t * 10))
    amp[5:8, 5:8] = values
    return sector(t, amp)


# (name, bad sector pair): every one must be dropped by both sector consumers
BAD_SECTORS = {   # case: (bad sector pair at t, what the logged reason says)
    'unknown encoding': (lambda t: sector(t, encoding='rgb8'), 'rgb8'),
    'data short of its step': (_short, 'short'),
    'fewer beams than the geometry': (lambda t: sector(t, amplitudes(1)[:, :40]), 'beams'),
    'angle_increment 1e-30': (lambda t: sector(t, angle_increment=1e-30, angle_max=GEOM.angle_min + 80e-30),
                              'beams per turn'),
    'angle_increment 1e-5': (lambda t: sector(t, angle_increment=1e-5, angle_max=GEOM.angle_min + 80e-5),
                             'beams per turn'),
    'angle_increment 0': (lambda t: sector(t, angle_increment=0.0, angle_max=GEOM.angle_min), 'angle_increment'),
    'angle_increment NaN': (lambda t: sector(t, angle_increment=math.nan), 'not finite'),
    'span wider than 2 pi': (lambda t: sector(t, angle_increment=0.1, angle_max=GEOM.angle_min + 8.0), 'full turn'),
    'range_max 3e38': (lambda t: sector(t, range_max=3e38), 'beyond any sonar'),
    'range_min above range_max': (lambda t: sector(t, range_min=40.0), 'range_min'),
    'negative range_min': (lambda t: sector(t, range_min=-1.0), 'range_min'),
    'NaN amplitude': (lambda t: _with(t, np.nan), 'NaN'),
    'infinite amplitude': (lambda t: _with(t, np.inf), 'infinite'),
    'negative amplitudes': (lambda t: _with(t, -2.0), 'negative'),
    'all negative': (lambda t: sector(t, -amplitudes(2)), 'negative'),
    'stale stamp (0.5 s old)': (lambda t: sector(t - 1.5), 'not newer than the last'),
    'repeated stamp': (lambda t: sector(t - 1.0), 'not newer than the last'),
}


class Harness:
    """A node driven through its own subscription callbacks; its publications recorded."""

    def __init__(self, node, outputs: list[str]):
        self.node = node
        self.subs = {s.topic_name: s for s in node.subscriptions}
        self.out: list = []
        self.said: list[str] = []
        say = node.say
        node.say = lambda severity, text, reason=None: (self.said.append(text), say(severity, text, reason))
        for name in outputs:   # 'pub_det' on the node, 'out.pub_tracks' on its track output
            owner = node
            for part in name.split('.')[:-1]:
                owner = getattr(owner, part)
            getattr(owner, name.split('.')[-1]).publish = lambda m, name=name: self.out.append((name, m))

    def feed(self, topic: str, msg) -> None:
        self.subs[topic].callback(msg)

    def sector(self, pair) -> None:
        self.feed('/sonar/sector', pair[0])
        self.feed('/sonar/sector_info', pair[1])

    def drops(self) -> int:
        return sum(self.node.diag.dropped.values())


SECTOR_NODES = {
    'active_detector': ('sonar_tracking.nodes.active_detector', 'ActiveDetectorNode', ['pub_det', 'pub_threshold']),
    'fls_features': ('sonar_tracking.nodes.fls_features', 'FlsFeaturesNode', ['pub_image', 'pub_regions']),
}


def make(inproc, module, cls, outputs, **params):
    import importlib
    return Harness(inproc(getattr(importlib.import_module(module), cls), **params), outputs)


@pytest.mark.parametrize('case', sorted(BAD_SECTORS))
@pytest.mark.parametrize('name', sorted(SECTOR_NODES))
def test_sector_consumers_drop_bad_sectors_and_stay_unchanged(inproc, name, case):
    module, cls, outputs = SECTOR_NODES[name]
    params = {'image.publish': 'sector'} if name == 'fls_features' else {}
    node = make(inproc, module, cls, outputs, **params)
    ref = make(inproc, module, cls, outputs, **params)
    for h in (node, ref):
        h.sector(sector(1.0))
        h.sector(sector(2.0))
    before = node.drops()
    bad, reason = BAD_SECTORS[case]
    node.sector(bad(2.5))
    assert node.drops() == before + 1, f'{case}: not dropped'
    assert reason in node.said[-1], f'{case}: the log says {node.said[-1]!r}'
    for h in (node, ref):
        h.sector(sector(3.0))
    assert node.out == ref.out, f'{case}: the next good output differs from a node that never saw it'
    assert len(node.out) == 3 * len(outputs)


def test_an_all_zero_sector_is_no_echo_for_both_consumers(inproc):
    for module, cls, outputs in SECTOR_NODES.values():
        h = make(inproc, module, cls, outputs, **({'image.publish': 'sector'} if 'fls' in module else {}))
        h.sector(sector(1.0, np.zeros(GEOM.shape, np.float32)))
        assert h.drops() == 0 and len(h.out) == len(outputs), cls


def test_bad_odometry_is_dropped_and_the_static_pose_kept(inproc):
    from nav_msgs.msg import Odometry
    for module, cls, outputs in SECTOR_NODES.values():
        h = make(inproc, module, cls, outputs)
        odo = Odometry()
        odo.header.stamp = ma.ns_to_stamp(10**9)
        odo.pose.pose.orientation.w = math.nan
        h.feed('/platform/odometry', odo)
        assert h.drops() == 1 and not h.node.input.has_odometry, cls


def detections(t: float, n=5, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed + int(t * 10))
    rec = np.zeros(n, ma.DETECTION_DTYPE)
    rec['x'] = np.r_[100.0 + 5.0 * t, rng.uniform(-500, 500, n - 1)]
    rec['y'] = np.r_[50.0, rng.uniform(-500, 500, n - 1)]
    rec['cov_xx'] = rec['cov_yy'] = 16.0
    rec['clutter_density'] = 1e-5
    return rec


def cloud(t: float, records) -> object:
    return ma.array_to_cloud(records, stamp_ns=int(round(t * 1e9)), frame_id='world')


def _short_cloud(t):
    c = cloud(t, detections(t))
    c.data = bytes(c.data)[:10]
    return c


BAD_DETECTIONS = {
    'data short': (_short_cloud, 'short'),
    'no x and y': (lambda t: cloud(t, np.zeros(2, [('range', '<f8')])), 'need fields x and y'),
    'stale stamp (0.5 s old)': (lambda t: cloud(t - 1.5, detections(t - 1.5)), 'not newer than the last'),
    'repeated stamp': (lambda t: cloud(t - 1.0, detections(t - 1.0)), 'not newer than the last'),
    'unknown field datatype': (lambda t: _bad_datatype(t), 'datatype 42'),
}


def _bad_datatype(t):
    from sensor_msgs.msg import PointCloud2, PointField
    msg = PointCloud2(height=1, width=1, point_step=8, row_step=8, data=bytes(8),
                      fields=[PointField(name='x', offset=0, datatype=42, count=1)])
    msg.header.stamp = ma.ns_to_stamp(int(t * 1e9))
    return msg


@pytest.mark.parametrize('case', sorted(BAD_DETECTIONS))
def test_imm_ipda_tracker_drops_bad_detections_and_keeps_its_tracks(inproc, case):
    args = ('sonar_tracking.nodes.imm_ipda_tracker', 'ImmIpdaTrackerNode', ['out.pub_tracks'])
    node, ref = make(inproc, *args, publish_tentative=True), make(inproc, *args, publish_tentative=True)
    for h in (node, ref):
        for t in (1.0, 2.0):
            h.feed('/detections', cloud(t, detections(t)))
    before = node.drops()
    bad, reason = BAD_DETECTIONS[case]
    node.feed('/detections', bad(2.5))
    assert node.drops() == before + 1, case
    assert reason in node.said[-1], node.said[-1]
    for h in (node, ref):
        h.feed('/detections', cloud(3.0, detections(3.0)))
    assert node.out == ref.out and len(node.out) == 3


def test_bad_rows_go_one_by_one_and_the_rest_is_tracked(inproc):
    args = ('sonar_tracking.nodes.imm_ipda_tracker', 'ImmIpdaTrackerNode', ['out.pub_tracks'])
    h = make(inproc, *args, publish_tentative=True)
    rows = detections(1.0, n=6)
    rows['x'][1] = np.nan
    rows['cov_xx'][2], rows['cov_xy'][2] = 1.0, 5.0
    rows['clutter_density'][3] = 0.0
    h.feed('/detections', cloud(1.0, rows))
    assert len(h.out) == 1 and h.node.tracker.report.n_measurements == 6 and len(h.node.tracker.report.rejected) == 3
    said = h.said[-1]
    assert 'dropped 3 of 6' in said and 'not finite' in said and 'positive definite' in said and 'clutter' in said


def test_a_nan_existence_track_never_becomes_the_esc_focus(inproc):
    module, cls, outputs = SECTOR_NODES['active_detector']
    h = make(inproc, module, cls, outputs, **{'esc.density_source': 'best_track'})
    tracks = np.zeros(2, ma.TRACK_DTYPE)
    tracks['confirmed'] = 1
    tracks['x'], tracks['y'], tracks['existence'] = [10.0, 20.0], [1.0, 2.0], [np.nan, 0.5]
    h.feed('/tracks', cloud(1.0, tracks))
    assert h.node.best_track == (20.0, 2.0)
    tracks['existence'] = np.nan
    h.feed('/tracks', cloud(2.0, tracks))
    assert h.node.best_track is None


GRID = ImageGrid(resolution=0.1, width=120, height=100, origin_x=0.0, origin_y=-5.0)


def frame(t: float):
    rng = np.random.default_rng(int(t * 10))
    img = rng.exponential(1.0, GRID.shape).astype(np.float32)
    x, y = 4.0 + 0.2 * t, 0.0
    col, row = int((x - GRID.origin_x) / 0.1), int((y - GRID.origin_y) / 0.1)
    img[row - 2:row + 3, col - 2:col + 3] = 20.0
    ns = int(round(t * 1e9))
    reg = np.zeros(1, ma.REGION_DTYPE)
    reg['x'], reg['y'], reg['range'] = x, y, x
    return {'image': ma.array_to_image(img, '32FC1', stamp_ns=ns, frame_id='world'),
            'info': grid_to_map_info(GRID, ns), 'regions': cloud(t, reg)}


def _bad_frame(t, part, change):
    f = frame(t)
    f[part] = change(f[part])
    return f


def _tilted(info):
    info.origin.orientation.x, info.origin.orientation.w = 1.0, 0.0
    return info


def _pixels(value):
    def change(msg):
        a = ma.image_to_array(msg).copy()
        a[3, 3] = value
        return ma.array_to_image(a, '32FC1', stamp_ns=ma.header_ns(msg), frame_id='world')
    return change


def _info(**changes):
    def change(info):
        for k, v in changes.items():
            setattr(info, k, v)
        return info
    return change


BAD_FRAMES = {
    'mono8 image': (lambda t: _bad_frame(t, 'image', lambda m: ma.array_to_image(
        (ma.image_to_array(m)).astype(np.uint8), 'mono8', stamp_ns=ma.header_ns(m))), 'must be 32FC1'),
    'NaN pixel': (lambda t: _bad_frame(t, 'image', _pixels(np.nan)), 'NaN'),
    'negative pixel': (lambda t: _bad_frame(t, 'image', _pixels(-1.0)), 'negative'),
    'tilted image_info': (lambda t: _bad_frame(t, 'info', _tilted), 'tilted'),
    'resolution 1e-9': (lambda t: _bad_frame(t, 'info', _info(resolution=1e-9)), 'resolution'),
    '8000 x 8000 image_info': (lambda t: _bad_frame(t, 'info', _info(width=8000, height=8000)), 'more than'),
    'regions without x, y': (lambda t: _bad_frame(t, 'regions', lambda m: cloud(t, np.zeros(1, [('range', '<f8')]))),
                             'need fields x and y'),
    'stale stamp': (lambda t: frame(t - 1.5), 'not newer than the last'),
}


@pytest.mark.parametrize('case', sorted(BAD_FRAMES))
def test_gpf_tracker_drops_bad_frames_and_keeps_its_tracks(inproc, case):
    args = ('sonar_tracking.nodes.gpf_tracker', 'GpfTrackerNode', ['out.pub_tracks'])
    node, ref = make(inproc, *args, publish_tentative=True), make(inproc, *args, publish_tentative=True)

    def send(h, f):
        h.feed('/fls/image_info', f['info'])
        h.feed('/fls/image', f['image'])
        h.feed('/fls/regions', f['regions'])

    for h in (node, ref):
        for t in (1.0, 2.0):
            send(h, frame(t))
    before = node.drops()
    bad, reason = BAD_FRAMES[case]
    send(node, bad(2.5))
    assert node.drops() == before + 1, case
    assert reason in node.said[-1], node.said[-1]
    for h in (node, ref):
        send(h, frame(3.0))
    assert node.out == ref.out and len(node.out) == 3
    assert len(ma.cloud_to_array(node.out[-1][1])) >= 1


def test_round_off_negatives_are_no_fault(inproc):
    h = make(inproc, 'sonar_tracking.nodes.gpf_tracker', 'GpfTrackerNode', ['out.pub_tracks'])
    f = _bad_frame(1.0, 'image', _pixels(-1.5e-15))
    for part, topic in (('info', '/fls/image_info'), ('image', '/fls/image'), ('regions', '/fls/regions')):
        h.feed(topic, f[part])
    assert h.drops() == 0 and len(h.out) == 1
    assert copy  # deep copies are not needed: every case builds its own messages


def _feed_tracker(h, t, kind):
    if kind == 'imm':
        h.feed('/detections', cloud(t, detections(t)))
    else:
        f = frame(t)
        for part, topic in (('info', '/fls/image_info'), ('image', '/fls/image'), ('regions', '/fls/regions')):
            h.feed(topic, f[part])


@pytest.mark.parametrize('name', ['active_detector', 'fls_features', 'imm_ipda_tracker', 'gpf_tracker'])
def test_a_jump_back_restarts_the_node_as_new_and_ids_are_never_reused(inproc, name):
    if name in SECTOR_NODES:
        module, cls, outputs = SECTOR_NODES[name]
        params = {'image.publish': 'sector'} if name == 'fls_features' else {}
        node, fresh = make(inproc, module, cls, outputs, **params), make(inproc, module, cls, outputs, **params)
        for t in (11.0, 12.0, 13.0):
            node.sector(sector(t))
        node.sector(sector(1.0))       # 12 s back: a new recording
        fresh.sector(sector(1.0))
        assert node.out[-len(outputs):] == fresh.out and node.drops() == 0
        return
    kind = 'imm' if name == 'imm_ipda_tracker' else 'gpf'
    module = 'sonar_tracking.nodes.' + name
    cls = 'ImmIpdaTrackerNode' if kind == 'imm' else 'GpfTrackerNode'
    node, fresh = (make(inproc, module, cls, ['out.pub_tracks'], publish_tentative=True) for _ in range(2))
    for t in (11.0, 12.0, 13.0):
        _feed_tracker(node, t, kind)
    old_ids = set(ma.cloud_to_array(node.out[-1][1])['track_id'].tolist())
    _feed_tracker(node, 1.0, kind)
    _feed_tracker(fresh, 1.0, kind)
    mine, theirs = ma.cloud_to_array(node.out[-1][1]), ma.cloud_to_array(fresh.out[-1][1])
    assert old_ids and len(mine) == len(theirs) >= 1 and min(mine['track_id']) > max(old_ids)
    fields = [f for f in mine.dtype.names if f != 'track_id']
    assert all(np.array_equal(mine[f], theirs[f]) for f in fields), 'after the restart it tracks as a fresh node'


# --- odometry: one bad message never outlives its neighbours -------------------------------------


def odom(t: float, x: float | None = None, y: float = 0.0, yaw: float = 0.0):
    """The platform's odometry at ``t``: moving along x at 2 m/s unless ``x`` is given."""
    return ma.pose_to_odometry(2.0 * t if x is None else x, y, yaw, stamp_ns=int(round(t * 1e9)))


def _nan_orientation(t):
    msg = odom(t)
    msg.pose.pose.orientation.w = math.nan
    return msg


BAD_ODOMETRY = {   # case: (bad odometry at t, what the logged reason says)
    'stamped a year ahead': (lambda t: odom(t + 3.15e7, 2.0 * t), 'not confirmed'),
    'stamped a minute ahead': (lambda t: odom(t + 60.0, 2.0 * t), 'not confirmed'),
    'x = 1e300': (lambda t: odom(t, 1e300), 'beyond'),
    'y = -1e8': (lambda t: odom(t, 0.0, -1e8), 'beyond'),
    'NaN orientation': (_nan_orientation, 'not finite'),
}

ODOMETRY_NODES = {
    'active_detector': (*SECTOR_NODES['active_detector'], lambda n: n.input.pose),
    'fls_features': (*SECTOR_NODES['fls_features'], lambda n: n.input.pose),
    'imm_ipda_tracker': ('sonar_tracking.nodes.imm_ipda_tracker', 'ImmIpdaTrackerNode', ['out.pub_tracks'],
                         lambda n: n.coverage.pose),
    'gpf_tracker': ('sonar_tracking.nodes.gpf_tracker', 'GpfTrackerNode', ['out.pub_tracks'], lambda n: n.pose),
}


def _data(h, name, t):
    if name in SECTOR_NODES:
        h.sector(sector(t))
    else:
        _feed_tracker(h, t, 'imm' if name == 'imm_ipda_tracker' else 'gpf')


@pytest.mark.parametrize('case', sorted(BAD_ODOMETRY))
@pytest.mark.parametrize('name', sorted(ODOMETRY_NODES))
def test_bad_odometry_is_dropped_and_never_poisons_the_poses(inproc, name, case):
    """A bad odometry message among good ones (10 Hz): dropped and counted with its reason; every later
    pose, and every output, is that of a node that never saw it."""
    module, cls, outputs, poses = ODOMETRY_NODES[name]
    params = {'image.publish': 'sector'} if name == 'fls_features' else {}
    node, ref = (make(inproc, module, cls, outputs, **params) for _ in range(2))

    def run(h, bad=None):
        before = said = 0
        for step in range(5, 41):
            t = step / 10
            h.feed('/platform/odometry', odom(t))
            if bad is not None and step == 15:
                before, said = h.drops(), len(h.said)
                h.feed('/platform/odometry', bad(t + 0.05))
            if step % 10 == 5:
                _data(h, name, t - 0.5)
        return before, said

    run(ref)
    before, said = run(node, BAD_ODOMETRY[case][0])
    assert node.drops() == before + 1, f'{case}: not dropped once ({node.node.diag.dropped})'
    assert any(BAD_ODOMETRY[case][1] in s for s in node.said[said:]), node.said[said:]
    assert node.out == ref.out and len(node.out) == 4 * len(outputs)
    for t in (1.23, 2.5, 3.9):
        assert poses(node.node).pose_at(int(t * 1e9)) == poses(ref.node).pose_at(int(t * 1e9))


@pytest.mark.parametrize('second', [False, True], ids=['one odometry first', 'two odometry first'])
@pytest.mark.parametrize('name', sorted(SECTOR_NODES))
def test_after_a_jump_back_the_first_sector_takes_the_new_recordings_odometry(inproc, name, second):
    """A looping bag: the new recording's odometry arrives before its first sector; that sector is
    placed by it (as by a fresh node), not at ``sonar_pose``."""
    module, cls, outputs = SECTOR_NODES[name]
    params = {'image.publish': 'sector'} if name == 'fls_features' else {}
    node, fresh = (make(inproc, module, cls, outputs, **params) for _ in range(2))
    for t in (11.0, 12.0, 13.0):
        node.feed('/platform/odometry', odom(t, 500.0 + t))
        node.sector(sector(t))
    for h in (node, fresh):
        h.feed('/platform/odometry', odom(1.0, 40.0, 5.0, 0.3))
        if second:
            h.feed('/platform/odometry', odom(1.1, 40.2, 5.0, 0.3))
        h.sector(sector(1.0))
    assert node.out[-len(outputs):] == fresh.out and node.drops() == 0
    assert node.node.input.pose.pose_at(10**9) == fresh.node.input.pose.pose_at(10**9) == (40.0, 5.0, 0.3)


@pytest.mark.parametrize('pose', [[1.0, 2.0], [1.0, 2.0, 3.0, 4.0], [1e300, 0.0, 0.0], [0.0, math.nan, 0.0]])
def test_gpf_tracker_refuses_a_sonar_pose_that_is_not_x_y_yaw(inproc, pose):
    """At start-up the default is kept (and logged); at run time the change is refused; frames are tracked."""
    from rclpy.parameter import Parameter
    h = make(inproc, 'sonar_tracking.nodes.gpf_tracker', 'GpfTrackerNode', ['out.pub_tracks'], sonar_pose=pose)
    assert h.node.config.sonar_pose == (0.0, 0.0, 0.0)
    result = h.node.set_parameters([Parameter('sonar_pose', value=pose)])[0]
    assert not result.successful and 'sonar_pose' in result.reason
    _feed_tracker(h, 1.0, 'gpf')
    assert h.drops() == 0 and len(h.out) == 1

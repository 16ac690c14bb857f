"""The imm_ipda_tracker node over real DDS: tracks from synthetic /detections, outputs, parameters, bad input."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import sonar_tracking.msgs as ma

pytestmark = pytest.mark.ros

KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
CONFIG = Path(__file__).resolve().parents[2] / 'config' / 'imm_ipda.yaml'
RHO = 5e-5


def detections(rng, truth_xy, n_clutter, half=300.0):
    """DETECTION_DTYPE records: the target (if ``truth_xy``) and uniform clutter around it."""
    centre = np.zeros(2) if truth_xy is None else np.asarray(truth_xy, float)
    pts = [centre + rng.uniform(-half, half, (n_clutter, 2))]
    if truth_xy is not None:
        pts.insert(0, centre + rng.normal(0, 4.0, (1, 2)))
    xy = np.concatenate(pts)
    rec = np.zeros(len(xy), ma.DETECTION_DTYPE)
    rec['x'], rec['y'] = xy[:, 0], xy[:, 1]
    rec['range'] = np.hypot(xy[:, 0], xy[:, 1])
    rec['bearing'] = np.arctan2(xy[:, 1], xy[:, 0])
    rec['amplitude'] = 5.0
    rec['clutter_density'] = RHO
    rec['cov_xx'], rec['cov_xy'], rec['cov_yy'] = 16.0, 0.0, 16.0
    return rec


class Harness:
    """Publishes /detections (and odometry) to the tracker and collects its outputs."""

    def __init__(self, ros, launch, proc):
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import PointCloud2
        from visualization_msgs.msg import MarkerArray
        self.ros, self.launch, self.proc = ros, launch, proc
        node = ros.node
        self.pub = node.create_publisher(PointCloud2, '/detections', KEEP_ALL)
        self.pub_odom = node.create_publisher(Odometry, '/platform/odometry', KEEP_ALL)
        self.tracks, self.markers, self.diagnostics = [], [], []
        self.subs = [node.create_subscription(PointCloud2, '/tracks', self.tracks.append, KEEP_ALL),
                     node.create_subscription(MarkerArray, '/tracks/markers', self.markers.append, KEEP_ALL),
                     node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, KEEP_ALL)]
        # Our readers must be matched with the node's writers too, or its first outputs are lost.
        ros.wait(lambda: self.pub.get_subscription_count() > 0 and self.pub_odom.get_subscription_count() > 0
                 and all(s.get_publisher_count() > 0 for s in self.subs), 30.0, 'the tracker to come up')

    def _on_diag(self, msg):
        self.diagnostics.extend(s for s in msg.status if s.name.startswith('imm_ipda_tracker'))

    def send(self, stamp_s: float, records=None, msg=None):
        self.pub.publish(msg if msg is not None else
                         ma.array_to_cloud(records, stamp_ns=int(round(stamp_s * 1e9)), frame_id='world'))

    def wait_tracks(self, n, timeout=30.0):
        self.ros.wait(lambda: len(self.tracks) >= n, timeout, f'{n} /tracks messages')

    def stop(self) -> str:
        """SIGINT the node; its stderr (the log)."""
        return self.launch.stop(self.proc)

    def close(self):
        for s in self.subs:
            self.ros.node.destroy_subscription(s)
        self.ros.node.destroy_publisher(self.pub)
        self.ros.node.destroy_publisher(self.pub_odom)


def values(parameter_values) -> list:
    """Python values of rcl_interfaces/ParameterValue messages (bool, int, double, string)."""
    fields = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value'}
    return [getattr(v, fields[v.type]) for v in parameter_values]


@pytest.fixture
def tracker(ros, launch, request):
    params = getattr(request, 'param', ())
    proc = launch('imm_ipda_tracker', *params)
    h = Harness(ros, launch, proc)
    yield h
    h.close()


def test_tracks_a_target_and_publishes_tracks_markers_and_diagnostics(tracker):
    from sonar_tracking.msgs.odometry import pose_to_odometry
    rng = np.random.default_rng(40)
    tracker.pub_odom.publish(pose_to_odometry(-2000.0, 0.0, 0.0, stamp_ns=10**9))
    truth = np.array([100.0, 200.0])
    v = np.array([8.0, 4.0])
    n = 15
    for k in range(n):
        tracker.send(1.0 + k, detections(rng, truth + v * k, 4))
    tracker.wait_tracks(n)
    last = tracker.tracks[-1]
    assert last.header.frame_id == 'world' and ma.header_ns(last) == int(round((1.0 + n - 1) * 1e9))
    assert [ma.header_ns(m) for m in tracker.tracks] == [int(round((1.0 + k) * 1e9)) for k in range(n)]
    tr = ma.cloud_to_array(last)
    assert tr.dtype.names == ma.TRACK_DTYPE.names
    conf = tr[tr['confirmed'] == 1]
    assert len(conf) == 1, tr
    end = truth + v * (n - 1)
    assert np.hypot(conf['x'][0] - end[0], conf['y'][0] - end[1]) < 15.0
    assert np.hypot(conf['vx'][0] - v[0], conf['vy'][0] - v[1]) < 3.0
    assert all(np.isfinite(tr[f]).all() for f in ma.TRACK_DTYPE.names)
    # Markers: DELETEALL, then the confirmed track's sphere, label, arrow and ellipse.
    # (markers are for RViz: a reader that falls behind may miss some, never the newest)
    tracker.ros.wait(lambda: tracker.markers and tracker.markers[-1].markers[-1].header.stamp == last.header.stamp,
                     20.0, 'the markers of the last scan')
    marks = tracker.markers[-1].markers
    assert marks[0].action == 3 and len(marks) == 5
    assert {m.ns for m in marks[1:]} == {'tracks/position', 'tracks/label', 'tracks/velocity', 'tracks/covariance'}
    # Diagnostics: counts, rate, latency, the platform pose it noted (the odometry is another topic, so
    # it may arrive after the last scan: the pose is read when the report is published).
    def status():
        return [dict((kv.key, kv.value) for kv in s.values) for s in tracker.diagnostics]
    tracker.ros.wait(lambda: any(v.get('processed') == str(n) and 'platform_pose' in v for v in status()), 20.0,
                     'diagnostics with the pose after all scans')
    values = next(v for v in status() if v.get('processed') == str(n) and 'platform_pose' in v)
    assert values['confirmed'] == '1' and int(values['tracks']) >= 1
    assert float(values['latency_median_ms']) > 0 and 'rate_hz' in values
    assert values['platform_pose'].startswith('x -2000.00 m, y 0.00 m')


def test_no_detections_give_an_empty_tracks_message(tracker):
    tracker.send(5.0, np.zeros(0, ma.DETECTION_DTYPE))
    tracker.wait_tracks(1)
    msg = tracker.tracks[0]
    assert msg.width == 0 and len(msg.fields) == len(ma.TRACK_DTYPE.names)
    tracker.ros.wait(lambda: len(tracker.markers) >= 1, 10.0, 'markers')
    assert [m.action for m in tracker.markers[0].markers] == [3]           # DELETEALL only


@pytest.mark.parametrize('tracker', [('detection.probability:=-1.0', 'imm.models:=cv,spin', 'marker_scale:=5.0',
                                      'publish_tentative:=true')],
                         indirect=True)
def test_parameters_refuse_bad_values_with_a_reason_and_apply_good_ones(tracker):
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter
    ros = tracker.ros
    setc = ros.node.create_client(SetParameters, '/imm_ipda_tracker/set_parameters')
    getc = ros.node.create_client(GetParameters, '/imm_ipda_tracker/get_parameters')
    assert setc.wait_for_service(timeout_sec=20.0) and getc.wait_for_service(timeout_sec=20.0)

    def set_(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return ros.call(setc, req).results[0]

    def get(*names):
        return values(ros.call(getc, GetParameters.Request(names=list(names))).values)

    # Start-up values that break a rule were replaced by the defaults; a good one was kept.
    assert get('detection.probability', 'imm.models', 'marker_scale') == [0.9, 'cv,ccw,cw', 5.0]
    r = set_('detection.probability', 1.5)
    assert not r.successful and 'detection.probability' in r.reason
    r = set_('existence.terminate', 0.5)
    assert not r.successful and 'existence.terminate' in r.reason
    r = set_('world_frame', 'map')
    assert not r.successful and 'read-only' in r.reason
    assert set_('detection.probability', 0.7).successful
    assert set_('clutter.density', 1).successful       # an integer for a double is accepted
    # A new mode set restarts the tracker: new tracks carry only the CV mode.
    rng = np.random.default_rng(42)
    tracker.send(1.0, detections(rng, (0.0, 0.0), 2))
    tracker.wait_tracks(1)
    assert set_('imm.models', 'cv').successful
    tracker.send(2.0, detections(rng, (8.0, 4.0), 2))
    tracker.wait_tracks(2)
    tr = ma.cloud_to_array(tracker.tracks[-1])
    assert len(tr) and np.all(tr['mode_cv'] == 1.0)
    err = tracker.stop()
    assert 'detection.probability' in err and 'imm.models' in err
    ros.node.destroy_client(setc)
    ros.node.destroy_client(getc)


def test_parameter_file_holds_the_paper_values(ros, launch):
    from rcl_interfaces.srv import GetParameters
    proc = launch('imm_ipda_tracker', params_file=CONFIG)
    client = ros.node.create_client(GetParameters, '/imm_ipda_tracker/get_parameters')
    assert client.wait_for_service(timeout_sec=20.0)
    names = ['imm.mode_stay_probability', 'imm.turn_rate_ccw_deg', 'detection.probability', 'clutter.source']
    res = ros.call(client, GetParameters.Request(names=names))
    assert values(res.values) == [0.98, 3.0, 0.57, 'detection']
    assert proc.poll() is None
    ros.node.destroy_client(client)

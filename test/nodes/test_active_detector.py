"""The active_detector node over real DDS: detections, services, parameters, bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

import sonar_tracking.msgs as ma
from sonar_tracking.sim import SimConfig, Simulator

pytestmark = pytest.mark.ros

KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


class Harness:
    """Publishes sector pairs to the detector and collects what it publishes."""

    def __init__(self, ros):
        from sensor_msgs.msg import Image, LaserScan, PointCloud2
        from std_msgs.msg import Float64
        self.ros = ros
        node = ros.node
        self.pub_img = node.create_publisher(Image, '/sonar/sector', KEEP_ALL)
        self.pub_info = node.create_publisher(LaserScan, '/sonar/sector_info', KEEP_ALL)
        self.detections, self.thresholds = [], []
        self.subs = [node.create_subscription(PointCloud2, '/detections', self.detections.append, KEEP_ALL),
                     node.create_subscription(Float64, '/detector/threshold',
                                              lambda m: self.thresholds.append(m.data), LATCHED)]
        self.sim = Simulator(SimConfig.for_scenario('scenario1'), np.random.default_rng(0))
        ros.wait(lambda: self.pub_img.get_subscription_count() > 0 and self.pub_info.get_subscription_count() > 0
                 and self.thresholds and self.subs[0].get_publisher_count() > 0, 30.0, 'the detector to come up')

    def send(self, stamp_s: float, image=None, info=None):
        s = self.sim.next_sector()
        ns = int(stamp_s * 1e9)
        img = image if image is not None else ma.array_to_image(s.amplitudes, stamp_ns=ns, frame_id='sonar')
        scan = info if info is not None else ma.geometry_to_scan(s.geometry, stamp_ns=ns, frame_id='sonar')
        self.pub_img.publish(img)
        self.pub_info.publish(scan)
        return s

    def wait_detections(self, n, timeout=20.0):
        self.ros.wait(lambda: len(self.detections) >= n, timeout, f'{n} detection messages')

    def close(self):
        for s in self.subs:
            self.ros.node.destroy_subscription(s)
        self.ros.node.destroy_publisher(self.pub_img)
        self.ros.node.destroy_publisher(self.pub_info)


@pytest.fixture
def harness(ros, launch):
    proc = launch('active_detector', 'sonar_pose:=[-2000.0, 0.0, 0.0]')
    h = Harness(ros)
    h.proc = proc
    yield h
    h.close()


def call(ros, srv_type, name, request):
    client = ros.node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=20.0), name
    try:
        # A reset is not idempotent (its reply reports the state it reset from): never sent twice.
        return ros.call(client, request, resend=20.0 if srv_type.__name__ == 'Trigger' else 2.0)
    finally:
        ros.node.destroy_client(client)


def test_detections_are_world_frame_records_with_clutter_density(harness):
    s = harness.send(1.0)
    harness.wait_detections(1)
    msg = harness.detections[-1]
    det = ma.cloud_to_array(msg)
    assert msg.header.frame_id == 'world' and ma.header_ns(msg) == 10**9
    assert det.dtype == ma.DETECTION_DTYPE
    assert len(det) == int((s.amplitudes > 3.0).sum())
    assert np.allclose(det['x'], -2000.0 + det['range'] * np.cos(det['bearing']))
    assert (det['clutter_density'] > 0).all() and (det['cov_xx'] > 0).all()


def test_services_enable_and_reset(harness, ros):
    from std_srvs.srv import SetBool, Trigger
    for k in range(1, 6):
        harness.send(float(k))
    harness.wait_detections(5)
    ros.wait(lambda: len(harness.thresholds) >= 6, 10.0, 'thresholds')
    moving = harness.thresholds[-1]
    assert moving != 3.0  # ESC has moved it
    r = call(ros, SetBool, '/active_detector/esc/enable', SetBool.Request(data=False))
    assert r.success and 'frozen' in r.message
    n = len(harness.thresholds)
    for k in range(6, 10):
        harness.send(float(k))
    harness.wait_detections(9)
    ros.wait(lambda: len(harness.thresholds) >= n + 4, 10.0, 'thresholds')
    assert len(set(harness.thresholds[n:])) == 1
    state = json.loads(call(ros, Trigger, '/active_detector/esc/reset', Trigger.Request()).message)
    assert state['threshold'] == 3.0 and state['scan_count'] == 0 and state['esc_enabled'] is False
    assert state['reset_from']['scan_count'] == 9 and state['reset_from']['threshold'] == harness.thresholds[-2]
    assert set(state) >= {'threshold', 'clutter_density', 'scan_count', 'desired_clutter_density'}
    call(ros, SetBool, '/active_detector/esc/enable', SetBool.Request(data=True))
    harness.send(10.0)
    harness.wait_detections(10)
    state = json.loads(call(ros, Trigger, '/active_detector/esc/reset', Trigger.Request()).message)
    assert state['esc_enabled'] is True


def test_parameters_in_and_out_of_range(harness, ros):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    def set_(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return call(ros, SetParameters, '/active_detector/set_parameters', req).results[0]

    r = set_('esc.dither_amplitude', 1.5)
    assert not r.successful and 'esc.dither_amplitude' in r.reason
    r = set_('threshold.initial', 50.0)
    assert not r.successful and 'threshold.initial' in r.reason
    r = set_('esc.desired_clutter_density', -1.0)
    assert not r.successful
    r = set_('esc.dither_decay', 'slow')
    assert not r.successful
    assert set_('threshold.initial', 4.0).successful
    ros.wait(lambda: harness.thresholds[-1] == 4.0, 10.0, 'the new initial threshold')
    assert set_('esc.dither_decay', 0.8).successful


def test_unmatched_sector_is_dropped_with_a_warning(harness):
    s = harness.sim.next_sector()
    harness.pub_img.publish(ma.array_to_image(s.amplitudes, stamp_ns=5 * 10**9))   # no geometry
    harness.send(6.0)
    harness.wait_detections(1)
    harness.proc.send_signal(2)
    _, err = harness.proc.communicate(timeout=10)
    assert 'never got its partner' in err
    assert [ma.header_ns(m) for m in harness.detections] == [6 * 10**9]


def test_desired_density_from_the_table(ros, launch):
    """esc.desired_clutter_density 0 looks rho_D up in config/desired_density.yaml (log-interpolated)."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    from sonar_tracking.core.detection import DesiredDensityTable
    from sonar_tracking.resources import config_path
    expected = DesiredDensityTable.load(config_path('desired_density.yaml')).lookup(9.0)
    proc = launch('active_detector', 'esc.desired_clutter_density:=0.0', 'esc.snr_db:=9.0')
    client = ros.node.create_client(SetParameters, '/active_detector/set_parameters')
    assert client.wait_for_service(timeout_sec=20.0)
    req = SetParameters.Request(parameters=[Parameter('esc.snr_db', value=40.0).to_parameter_msg()])
    r = ros.call(client, req).results[0]
    assert not r.successful and 'outside the table' in r.reason
    ros.node.destroy_client(client)
    proc.send_signal(2)
    _, err = proc.communicate(timeout=10)
    assert f'desired clutter density {expected:.3g} /m^2' in err

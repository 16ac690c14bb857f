"""input_qos: every sensor-data consumer reads best-effort drivers with ``sensor_data``; a reliable
reader never matches a best-effort writer. The nodes run in this process (own context, own executor)."""
from __future__ import annotations

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import SectorGeometry

pytestmark = pytest.mark.ros

# node class, its sensor-data topics and their types (imported lazily: rclpy after the DDS set-up)
CONSUMERS = {
    'active_detector': ('sonar_tracking.nodes.active_detector:ActiveDetectorNode',
                        [('sonar/sector', 'Image'), ('sonar/sector_info', 'LaserScan'),
                         ('platform/odometry', 'Odometry')]),
    'fls_features': ('sonar_tracking.nodes.fls_features:FlsFeaturesNode',
                     [('sonar/sector', 'Image'), ('sonar/sector_info', 'LaserScan'),
                      ('platform/odometry', 'Odometry')]),
    'imm_ipda_tracker': ('sonar_tracking.nodes.imm_ipda_tracker:ImmIpdaTrackerNode',
                         [('platform/odometry', 'Odometry'), ('sonar/sector_info', 'LaserScan')]),
    'gpf_tracker': ('sonar_tracking.nodes.gpf_tracker:GpfTrackerNode', [('platform/odometry', 'Odometry')]),
}
# topics from the package's own nodes: reliable whatever input_qos says
BETWEEN_NODES = {
    'active_detector': ['tracks'],
    'imm_ipda_tracker': ['detections'],
    'gpf_tracker': ['fls/image', 'fls/image_info', 'fls/regions'],
}


def _type(name):
    from nav_msgs.msg import MapMetaData, Odometry
    from sensor_msgs.msg import Image, LaserScan, PointCloud2
    return {'Image': Image, 'LaserScan': LaserScan, 'PointCloud2': PointCloud2, 'Odometry': Odometry,
            'MapMetaData': MapMetaData}[name]


@pytest.fixture
def node_under_test(inproc):
    """``start(name, **params)``: the package node ``name`` in this process."""
    import importlib

    def start(name, **params):
        module, cls = CONSUMERS[name][0].split(':')
        return inproc(getattr(importlib.import_module(module), cls), **params)
    return start


def best_effort(depth=10):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT)


@pytest.mark.parametrize('name', sorted(CONSUMERS))
def test_sensor_data_readers_match_best_effort_drivers(ros, node_under_test, name):
    node = node_under_test(name, input_qos='sensor_data')
    pubs = [ros.node.create_publisher(_type(t), f'/{topic}', best_effort()) for topic, t in CONSUMERS[name][1]]
    try:
        ros.wait(lambda: all(p.get_subscription_count() >= 1 for p in pubs), 20.0,
                 f'{name} to match every best-effort writer')
    finally:
        for p in pubs:
            ros.node.destroy_publisher(p)
    assert node.get_parameter('input_qos').value == 'sensor_data'


@pytest.mark.parametrize('name', sorted(CONSUMERS))
def test_reliable_readers_report_incompatible_best_effort_writers(ros, node_under_test, name):
    from rclpy.event_handler import PublisherEventCallbacks
    node_under_test(name)
    topic, t = CONSUMERS[name][1][0]
    incompatible = []
    callbacks = PublisherEventCallbacks(incompatible_qos=incompatible.append)
    pub = ros.node.create_publisher(_type(t), f'/{topic}', best_effort(), event_callbacks=callbacks)
    try:
        ros.wait(lambda: incompatible, 20.0, f'the incompatible-QoS event of {name}\'s reliable reader')
        assert pub.get_subscription_count() == 0
    finally:
        ros.node.destroy_publisher(pub)


def test_a_best_effort_sector_stream_gives_detections(ros, node_under_test):
    from rclpy.qos import QoSProfile
    from sensor_msgs.msg import Image, LaserScan, PointCloud2
    node_under_test('active_detector', input_qos='sensor_data', **{'esc.enabled': False, 'threshold.initial': 5.0})
    got = []
    sub = ros.node.create_subscription(PointCloud2, '/detections', got.append, QoSProfile(depth=50))
    pub_img = ros.node.create_publisher(Image, '/sonar/sector', best_effort())
    pub_info = ros.node.create_publisher(LaserScan, '/sonar/sector_info', best_effort())
    geom = SectorGeometry(angle_min=-0.3, angle_increment=0.01, n_beams=61, range_min=1.0, range_max=40.0,
                          n_bins=80)
    amp = np.ones(geom.shape, np.float32)
    amp[40, 30] = 50.0
    try:
        ros.wait(lambda: pub_img.get_subscription_count() and pub_info.get_subscription_count()
                 and sub.get_publisher_count(), 20.0, 'matching')
        k = 0

        def send_until_detected():
            nonlocal k
            k += 1   # best effort may lose a message: send a new sector each time we look
            stamp = k * 10**9
            pub_img.publish(ma.array_to_image(amp, '32FC1', stamp_ns=stamp, frame_id='sonar'))
            pub_info.publish(ma.geometry_to_scan(geom, amplitudes=amp, stamp_ns=stamp, frame_id='sonar'))
            return any(m.width >= 1 for m in got)

        ros.wait(send_until_detected, 30.0, 'detections from a best-effort sector stream')
        det = ma.cloud_to_array(next(m for m in got if m.width >= 1))
        assert det['range'][0] == pytest.approx(geom.ranges()[40]) and det['bearing'][0] == pytest.approx(0.0, abs=1e-6)
    finally:
        ros.node.destroy_subscription(sub)
        ros.node.destroy_publisher(pub_img)
        ros.node.destroy_publisher(pub_info)


@pytest.mark.parametrize('name', sorted(BETWEEN_NODES))
def test_topics_between_the_packages_nodes_stay_reliable_under_sensor_data(ros, node_under_test, name):
    """``input_qos: sensor_data`` (the sensor presets) is for the driver's topics: a reader of another
    node of the package stays reliable, so a burst of large frames is not lost (as the graph shows it)."""
    from rclpy.qos import ReliabilityPolicy
    node_under_test(name, input_qos='sensor_data')

    def readers(topic):
        return [i for i in ros.node.get_subscriptions_info_by_topic(f'/{topic}') if i.node_name == name]
    for topic in BETWEEN_NODES[name]:
        ros.wait(lambda topic=topic: readers(topic), 20.0, f'{name} reading /{topic}')
        assert [i.qos_profile.reliability for i in readers(topic)] == [ReliabilityPolicy.RELIABLE], topic
    for topic, _ in CONSUMERS[name][1]:
        ros.wait(lambda topic=topic: readers(topic), 20.0, f'{name} reading /{topic}')
        assert [i.qos_profile.reliability for i in readers(topic)] == [ReliabilityPolicy.BEST_EFFORT], topic

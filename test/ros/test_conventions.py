"""What a ROS 2 user expects of the nodes: stamps on the system's clock, /clock with simulated time,
the ESC service and its parameter in agreement, a threshold that cannot go stale."""
from __future__ import annotations

import statistics
import time

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import SectorGeometry

pytestmark = pytest.mark.ros


def test_simulator_stamps_wall_time_at_rate_1(ros, inproc):
    from sensor_msgs.msg import Image

    from sonar_tracking.nodes.seaking_sim import SeaKingSimNode
    lag = []
    sub = ros.node.create_subscription(Image, '/sonar/sector',
                                       lambda m: lag.append(time.time_ns() - ma.header_ns(m)), 50)
    try:
        inproc(SeaKingSimNode, scenario='fls3', rate=1.0)
        ros.wait(lambda: len(lag) >= 10, 60.0, '10 sectors')
        # a stamp is the wall time the sector is due; what we see adds the delivery delay
        assert abs(statistics.median(lag)) < 0.05e9, lag
    finally:
        ros.node.destroy_subscription(sub)


def test_simulator_off_wall_time_stamps_simulated_time_and_publishes_clock(ros, inproc):
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image

    from sonar_tracking.nodes.seaking_sim import SeaKingSimNode
    stamps, clocks = [], []
    subs = [ros.node.create_subscription(Image, '/sonar/sector', lambda m: stamps.append(ma.header_ns(m)), 100),
            ros.node.create_subscription(Clock, '/clock', lambda m: clocks.append(ma.stamp_to_ns(m.clock)), 100)]
    try:
        inproc(SeaKingSimNode, scenario='fls3', rate=4.0, publish_clock=True)
        ros.wait(lambda: len(stamps) >= 3 and len(clocks) >= 3, 60.0, 'sectors and /clock')
        assert stamps[0] < 10**11, 'simulated time from stamp_offset 0, not the wall clock'
        assert set(stamps[:3]) <= set(clocks), '/clock carries the stamps of the sectors'
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)


def test_esc_service_and_parameter_agree_and_the_threshold_is_never_stale(ros, inproc):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import Image, LaserScan
    from std_msgs.msg import Float64
    from std_srvs.srv import SetBool

    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    node = inproc(ActiveDetectorNode)
    client = ros.node.create_client(SetBool, '/active_detector/esc/enable')
    pub_img = ros.node.create_publisher(Image, '/sonar/sector', 10)
    pub_info = ros.node.create_publisher(LaserScan, '/sonar/sector_info', 10)
    try:
        assert client.wait_for_service(timeout_sec=20.0)
        assert ros.call(client, SetBool.Request(data=False)).success
        assert node.get_parameter('esc.enabled').value is False and not node.detector.enabled
        assert ros.call(client, SetBool.Request(data=True)).success
        assert node.get_parameter('esc.enabled').value is True and node.detector.enabled
        # ESC moves the threshold scan by scan; a late reader gets only the newest value
        geom = SectorGeometry(angle_min=-0.3, angle_increment=0.01, n_beams=61, range_min=1.0, range_max=40.0,
                              n_bins=80)
        rng = np.random.default_rng(1)
        ros.wait(lambda: pub_img.get_subscription_count() and pub_info.get_subscription_count(), 20.0, 'matching')
        for k in range(1, 6):
            amp = rng.exponential(1.0, geom.shape).astype(np.float32)
            pub_img.publish(ma.array_to_image(amp, '32FC1', stamp_ns=k * 10**9))
            pub_info.publish(ma.geometry_to_scan(geom, amplitudes=amp, stamp_ns=k * 10**9))
        ros.wait(lambda: node.detector.scans == 5, 20.0, 'five scans')
        late = []
        sub = ros.node.create_subscription(Float64, '/detector/threshold', late.append,
                                           QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        ros.wait(lambda: late, 20.0, 'the latched threshold')
        applied = float(node.diag.values['threshold'])
        assert len(late) == 1 and late[0].data == pytest.approx(applied, abs=1e-4)
        ros.node.destroy_subscription(sub)
    finally:
        ros.node.destroy_publisher(pub_img)
        ros.node.destroy_publisher(pub_info)
        ros.node.destroy_client(client)

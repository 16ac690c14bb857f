"""The one rule for following a topic's publishers (``offered_profile``) and the rclpy -> bag QoS record."""
from __future__ import annotations

import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

from sonar_tracking.ros.qos import offered_profile, qos_from_rclpy

R, B, U = QosReliability.RELIABLE, QosReliability.BEST_EFFORT, QosReliability.UNKNOWN
T, V = QosDurability.TRANSIENT_LOCAL, QosDurability.VOLATILE


def offer(reliability: QosReliability, durability: QosDurability = V) -> Qos:
    zero = QosTime(0, 0)
    return Qos(QosHistory.KEEP_LAST, 10, reliability, durability, zero, zero, QosLiveliness.AUTOMATIC, zero, False)


@pytest.mark.parametrize('offers, reliability, durability', [
    ([], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),            # no publisher known yet
    ([offer(R)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),
    ([offer(R), offer(B)], ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE),
    ([offer(U)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),    # an old bag: ROS 2's default
    ([offer(R, T), offer(R, T)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL),
    ([offer(R, T), offer(R, V)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),
])
def test_the_profile_follows_what_the_publishers_offered(offers, reliability, durability):
    p = offered_profile(offers, depth=7)
    assert (p.reliability, p.durability, p.depth) == (reliability, durability, 7)


def test_an_rclpy_profile_becomes_the_bag_record_of_it():
    latched = qos_from_rclpy(QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    assert (latched.reliability, latched.durability, latched.depth) == (R, T, 1)
    sensor = qos_from_rclpy(qos_profile_sensor_data)
    assert sensor.reliability == B
    assert offered_profile([latched]).durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offered_profile([latched, sensor]).reliability == ReliabilityPolicy.BEST_EFFORT

"""Shared fixtures. DDS traffic of the tests stays on this machine, in a domain of its own."""
from __future__ import annotations

import os

import pytest

# Before any rclpy import: a per-run domain so parallel runs on one machine do not see each other.
os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


@pytest.fixture(scope='session')
def rosbags_types():
    """Message builder on the rosbags ROS 2 Jazzy typestore (dataclasses with numpy arrays)."""
    from rosbags.typesys import Stores, get_typestore

    from msg_adapters import RosbagsTypes
    return RosbagsTypes(get_typestore(Stores.ROS2_JAZZY))


@pytest.fixture(params=['rclpy', 'rosbags'])
def types(request, rosbags_types):
    """Both message representations: every adapter must work on each."""
    from msg_adapters import rclpy_types
    return rclpy_types() if request.param == 'rclpy' else rosbags_types


@pytest.fixture(scope='session')
def graph_node():
    """An rclpy node of the test process, for looking at the ROS graph."""
    import rclpy
    from rclpy.context import Context
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node('sonar_tracking_test_probe', context=context)
    yield node
    node.destroy_node()
    rclpy.shutdown(context=context)

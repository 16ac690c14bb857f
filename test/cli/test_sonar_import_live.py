"""projected_sonar_adapter: the live path for imaging sonars gives the importer's sectors.

The conversion is checked on every machine; the node against a best-effort publisher only where
``marine_acoustic_msgs`` is importable (built by ``python -m
sonar_tracking.cli.build_interfaces``; it is not among the ROS wheels).
"""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.io.importers import ImportOptions, projected_to_sector
from sonar_tracking.io.importers.msgdefs import register_builtin


def projected_msg(types, n_beams: int = 40, n_bins: int = 50, stamp_ns: int = 1_700_000_000_123_000_000):
    """A ProjectedSonarImage (message frame: z forward, y starboard) with uneven beams, uint8 counts."""
    az = np.arcsin(np.linspace(-1, 1, n_beams) * math.sin(math.radians(60)))
    dirs = [types.new('geometry_msgs/msg/Vector3', x=0.0, y=-math.sin(a), z=math.cos(a)) for a in az]
    values = (np.arange(n_bins * n_beams) % 101).astype(np.uint8).reshape(n_bins, n_beams)
    values[30, 35] = 255                           # a bright cell on the port side (beam 35 of 40)
    image = types.new('marine_acoustic_msgs/msg/SonarImageData', is_bigendian=False, dtype=0, beam_count=n_beams,
                      data=types.numeric_sequence(values.reshape(-1)))
    return types.new('marine_acoustic_msgs/msg/ProjectedSonarImage', header=ma.header(stamp_ns, 'oculus', types),
                     beam_directions=dirs, ranges=types.numeric_sequence(((np.arange(n_bins) + 0.5) * 0.1)
                                                                           .astype(np.float32)), image=image)


def test_convert_gives_the_importers_sector(rosbags_types):
    from sonar_tracking.nodes.projected_sonar_adapter import AdapterConfig, convert
    register_builtin(rosbags_types.typestore)
    msg = projected_msg(rosbags_types)
    image, scan, negatives = convert(msg, AdapterConfig())
    values, geometry, _ = projected_to_sector(msg, ImportOptions())
    got, geom = ma.sector_from_messages(image, scan)
    assert negatives == 0 and image.encoding == 'mono8' and image.header.frame_id == 'oculus'
    np.testing.assert_array_equal(got, values)
    assert geom.n_beams == 40 and math.isclose(geom.angle_min, -math.radians(60), abs_tol=1e-6)
    # The bright cell (port side, beam index 35 in the message) stays on the port side.
    row, col = np.unravel_index(np.argmax(got), got.shape)
    assert row == 30 and geom.bearings()[col] > 0


def test_live_adapter_reads_a_best_effort_publisher():
    pytest.importorskip('marine_acoustic_msgs.msg', reason='marine_acoustic_msgs not built here')
    import rclpy
    from marine_acoustic_msgs.msg import ProjectedSonarImage
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image

    from sonar_tracking.nodes.projected_sonar_adapter import ProjectedSonarAdapter
    context = Context()
    rclpy.init(context=context)
    try:
        node = ProjectedSonarAdapter(context=context,
                                     parameter_overrides=[Parameter('input_qos', value='sensor_data')])
        probe = rclpy.create_node('probe', context=context)
        pub = probe.create_publisher(ProjectedSonarImage, 'sonar_image', qos_profile_sensor_data)
        got = []
        probe.create_subscription(Image, 'sonar/sector', got.append, 10)
        ex = SingleThreadedExecutor(context=context)
        ex.add_node(node)
        ex.add_node(probe)
        msg = projected_msg(ma.rclpy_types())
        deadline = time.monotonic() + 20.0
        while not got and time.monotonic() < deadline:
            pub.publish(msg)
            ex.spin_once(timeout_sec=0.1)
        assert got, 'no sector from a best-effort ProjectedSonarImage publisher'
        assert (got[0].height, got[0].width) == (50, 40) and ma.header_ns(got[0]) == ma.header_ns(msg)
    finally:
        rclpy.try_shutdown(context=context)

"""How every process of the package runs ROS: DDS defaults and the ros2/demos main() pattern."""
from __future__ import annotations

import os
from importlib import resources
from typing import Callable

__all__ = ['run_node', 'configure_dds']


def configure_dds() -> None:
    """Use the package's Fast DDS profile unless the user chose one or another middleware.

    Must run before ``rclpy.init``: Fast DDS reads the profile when the participant is created.
    """
    rmw = os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    if 'fastrtps' in rmw and not os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(resources.files('sonar_tracking') / 'data' / 'fastdds.xml')


def run_node(factory: Callable[[], 'rclpy.node.Node'], args: list[str] | None = None) -> int:
    """Init rclpy, spin the node until Ctrl-C or shutdown, clean up; returns the exit status."""
    configure_dds()
    import rclpy
    from rclpy.executors import ExternalShutdownException
    rclpy.init(args=args)
    node = None
    try:
        node = factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0

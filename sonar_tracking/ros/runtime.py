"""How every process of the package runs ROS: DDS defaults, parent watch, the ros2/demos main()."""
from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
from collections.abc import Callable
from importlib import resources
from typing import TYPE_CHECKING

from sonar_tracking import process

if TYPE_CHECKING:
    import rclpy.node

__all__ = ['run_node', 'prepare_process', 'configure_dds', 'private_domain', 'exit_if_teardown_hangs']


def prepare_process() -> None:
    """Call first in every ROS entry point: DDS defaults, :func:`sonar_tracking.process.prepare`, and under
    ``sonar_stack`` a parent watch.

    ``sonar_stack`` sets ``SONAR_TRACKING_DIE_WITH_PARENT``: the process then asks Linux for
    SIGTERM when its parent dies (``PR_SET_PDEATHSIG``), so a killed stack leaves no orphans.
    """
    configure_dds()
    process.prepare()
    if os.environ.get('SONAR_TRACKING_DIE_WITH_PARENT'):
        try:
            ctypes.CDLL('libc.so.6', use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


def configure_dds() -> None:
    """Use the package's Fast DDS profile unless the user chose one or another middleware.

    Must run before ``rclpy.init``: Fast DDS reads the profile when the participant is created.
    """
    rmw = os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    if 'fastrtps' in rmw and not os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(resources.files('sonar_tracking') / 'data' / 'fastdds.xml')


def private_domain() -> int:
    """Put this process and the children it starts in a DDS domain of their own (from the pid), so a
    benchmark or test sees only its own nodes, whatever else runs on the machine. Before ``rclpy.init``."""
    domain = 101 + os.getpid() % 100   # 101-200: clear of the default 0 and of the tests' 1-100
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return domain


def run_node(factory: Callable[[], rclpy.node.Node], args: list[str] | None = None) -> int:
    """Init rclpy, spin the node until Ctrl-C or shutdown, clean up; returns the exit status."""
    prepare_process()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    rclpy.init(args=args)
    # Made before the node: a Ctrl-C while the node is being built (it is in the graph by then)
    # cannot meet an executor half made on a context already shut down.
    executor = SingleThreadedExecutor()
    node = None
    try:
        node = factory()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # Ctrl-C while the node was still being built: rclpy's signal handler shut the context down
        # under it, and the call that failed on it is a stop, not a failure.
        if rclpy.ok():
            raise
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def exit_if_teardown_hangs(status: int = 0, seconds: float = 10.0) -> None:
    """Leave the process with ``status`` if it is still here ``seconds`` from now. For a tool whose
    work is done (every message sent and acknowledged) before it tears ROS down: the teardown of
    rclpy and DDS can hang now and then (ros2/rclpy#456, eProsima/Fast-DDS#235), and a tool that
    never exits stalls whatever waits for it."""
    def leave() -> None:
        print(f'ROS teardown took over {seconds:g} s: exiting without it', file=sys.stderr, flush=True)
        os._exit(status)
    timer = threading.Timer(seconds, leave)
    timer.daemon = True
    timer.start()

"""QoS profiles of the package's topics, in one place.

Sensor input (sectors, odometry, detections, FLS frames) is read with the profile the node's
``input_qos`` parameter names:

* ``reliable`` (default): matches the package's own reliable publishers, which then pace
  themselves on the readers' acknowledgements (``seaking_sim rate:=0``, ``bag_replay --fast``);
* ``sensor_data``: best effort, the QoS most sonar drivers publish with. A best-effort reader
  matches both best-effort and reliable writers; a reliable reader never matches a best-effort
  writer, so a driver's topic stays silent until this is chosen.
"""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['INPUT_QOS', 'CLOCK_TOPIC', 'input_profile', 'output_profile', 'latest_profile']

INPUT_QOS = ('reliable', 'sensor_data')

#: ``/clock`` is global by ROS convention (every ``use_sim_time`` node reads it there), so it is
#: the one name a namespace does not move.
CLOCK_TOPIC = '/clock'


def input_profile(kind: str, depth: int = 50) -> QoSProfile:
    """Reader profile for sensor data: ``reliable`` or ``sensor_data`` (best effort), keep last ``depth``."""
    if kind not in INPUT_QOS:
        raise ValueError(f'input_qos {kind!r} is not one of {list(INPUT_QOS)}')
    reliability = ReliabilityPolicy.RELIABLE if kind == 'reliable' else ReliabilityPolicy.BEST_EFFORT
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=reliability,
                      durability=DurabilityPolicy.VOLATILE)


def output_profile(depth: int = 100) -> QoSProfile:
    """Writer profile of results: reliable, with a deep queue so a recorder that falls behind for a
    moment under load still gets every message (a reliable writer drops what leaves its queue)."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)


def latest_profile() -> QoSProfile:
    """A value whose newest sample is all that matters (the detector threshold): depth 1, transient
    local, so a late reader gets the current value and never an old one."""
    return QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)

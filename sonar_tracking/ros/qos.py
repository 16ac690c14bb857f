"""QoS profiles of the package's topics, and the rule for following a publisher's QoS, in one place.

Sensor input (sectors, odometry, detections, FLS frames) is read with the profile the node's
``input_qos`` parameter names:

* ``reliable`` (default): matches the package's own reliable publishers, which then pace
  themselves on the readers' acknowledgements (``seaking_sim rate:=0``, ``bag_replay --fast``);
* ``sensor_data``: best effort, the QoS most sonar drivers publish with. A best-effort reader
  matches both best-effort and reliable writers; a reliable reader never matches a best-effort
  writer, so a driver's topic stays silent until this is chosen.

Recording, replay and ``sonar_echo`` follow the QoS a topic's publishers offered
(:func:`offered_profile`): reliable unless one of them offered best effort (an unknown reliability,
as in old bags, counts as ROS 2's default, reliable), transient local when every one of them did.
:func:`qos_from_rclpy` turns an rclpy profile into the ``rosbags`` record a bag stores.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['INPUT_QOS', 'CLOCK_TOPIC', 'input_profile', 'output_profile', 'latest_profile', 'offered_profile',
           'qos_from_rclpy']

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


def offered_profile(offered: Sequence[Any], depth: int = 100) -> QoSProfile:
    """Reader or replay profile that follows what a topic's publishers offered (``rosbags`` ``Qos``
    records, as :func:`qos_from_rclpy` gives or a bag stores): reliable unless one offered best
    effort, transient local when all offered it (so a latched value is caught); no publisher known
    yet gives reliable and volatile."""
    reliable = all(q.reliability.name != 'BEST_EFFORT' for q in offered)
    transient = bool(offered) and all(q.durability.name == 'TRANSIENT_LOCAL' for q in offered)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)


def qos_from_rclpy(profile: QoSProfile) -> Any:
    """rosbags ``Qos`` of an rclpy ``QoSProfile`` (as offered by a publisher)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    def t(d: Any) -> QosTime:
        ns = int(d.nanoseconds)
        return QosTime(ns // 10**9, ns % 10**9)

    def enum(cls: Any, value: Any) -> Any:
        try:
            return cls(int(value))
        except ValueError:
            return cls.UNKNOWN

    return Qos(history=enum(QosHistory, profile.history), depth=int(profile.depth),
               reliability=enum(QosReliability, profile.reliability),
               durability=enum(QosDurability, profile.durability), deadline=t(profile.deadline),
               lifespan=t(profile.lifespan), liveliness=enum(QosLiveliness, profile.liveliness),
               liveliness_lease_duration=t(profile.liveliness_lease_duration),
               avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))

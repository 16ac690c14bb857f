"""Conversions between ``builtin_interfaces/Time`` and integer nanoseconds."""
from __future__ import annotations

from typing import Any

from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['stamp_to_ns', 'ns_to_stamp', 'header', 'header_ns']

_NS = 1_000_000_000


def stamp_to_ns(stamp: Any) -> int:
    """Nanoseconds of a ``Time`` (any object with ``sec`` and ``nanosec``)."""
    try:
        sec, nsec = int(stamp.sec), int(stamp.nanosec)
    except (AttributeError, TypeError, ValueError) as exc:
        raise AdapterError(f'stamp is not a builtin_interfaces/Time: {stamp!r}') from exc
    if not 0 <= nsec < _NS:
        raise AdapterError(f'stamp nanosec = {nsec} is outside [0, 1e9)')
    return sec * _NS + nsec


def ns_to_stamp(ns: int, types: MessageTypes | None = None) -> Any:
    """A ``builtin_interfaces/Time`` for ``ns`` nanoseconds (negative times are refused)."""
    ns = int(ns)
    if ns < 0:
        raise AdapterError(f'cannot represent negative time {ns} ns as a ROS stamp')
    sec, nsec = divmod(ns, _NS)
    return (types or rclpy_types()).new('builtin_interfaces/msg/Time', sec=sec, nanosec=nsec)


def header(stamp_ns: int, frame_id: str, types: MessageTypes | None = None) -> Any:
    """A ``std_msgs/Header``."""
    types = types or rclpy_types()
    return types.new('std_msgs/msg/Header', stamp=ns_to_stamp(stamp_ns, types), frame_id=frame_id)


def header_ns(msg: Any) -> int:
    """Stamp of ``msg.header`` in nanoseconds."""
    try:
        return stamp_to_ns(msg.header.stamp)
    except AttributeError as exc:
        raise AdapterError(f'{type(msg).__name__} has no header.stamp') from exc

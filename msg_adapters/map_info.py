"""``/fls/image_info``: the pixel <-> metres mapping of ``/fls/image`` as a ``nav_msgs/MapMetaData``.

An FLS image is laid out as an OccupancyGrid (``sonar_tracking.core.fls.grid``), so MapMetaData
describes it exactly: ``resolution`` [m/pixel], ``width`` (columns, along the grid x axis),
``height`` (rows), ``origin`` the pose of the outer corner of pixel (0, 0) in the Image's
``header.frame_id``, and ``map_load_time`` = the Image's ``header.stamp``, by which a consumer
pairs the two (:class:`~msg_adapters.pairing.StampPairer`). Works on rclpy messages and rosbags
dataclasses alike. Not re-exported by ``msg_adapters`` (it needs the FLS grid): import
``msg_adapters.map_info``.
"""
from __future__ import annotations

import math
from typing import Any

from sonar_tracking.core.fls.grid import ImageGrid

from .errors import AdapterError
from .stamps import ns_to_stamp
from .types import MessageTypes, rclpy_types

__all__ = ['grid_to_map_info', 'map_info_to_grid']


def grid_to_map_info(grid: ImageGrid, stamp_ns: int, types: MessageTypes | None = None) -> Any:
    """The MapMetaData of an image grid, stamped like its image."""
    types = types or rclpy_types()
    half = 0.5 * grid.origin_yaw
    pose = types.new('geometry_msgs/msg/Pose',
                     position=types.new('geometry_msgs/msg/Point', x=float(grid.origin_x), y=float(grid.origin_y),
                                        z=0.0),
                     orientation=types.new('geometry_msgs/msg/Quaternion', x=0.0, y=0.0, z=math.sin(half),
                                           w=math.cos(half)))
    return types.new('nav_msgs/msg/MapMetaData', map_load_time=ns_to_stamp(stamp_ns, types),
                     resolution=float(grid.resolution), width=int(grid.width), height=int(grid.height), origin=pose)


def map_info_to_grid(msg: Any) -> ImageGrid:
    """The ImageGrid of a MapMetaData; AdapterError if it is not a valid planar grid."""
    try:
        p, q = msg.origin.position, msg.origin.orientation
        values = dict(resolution=float(msg.resolution), width=int(msg.width), height=int(msg.height),
                      x=float(p.x), y=float(p.y), qx=float(q.x), qy=float(q.y), qz=float(q.z), qw=float(q.w))
    except AttributeError as exc:
        raise AdapterError(f'not a nav_msgs/MapMetaData: missing field {exc.name!r}') from exc
    norm = math.sqrt(values['qx'] ** 2 + values['qy'] ** 2 + values['qz'] ** 2 + values['qw'] ** 2)
    if not math.isfinite(norm) or abs(norm - 1.0) > 1e-3:
        raise AdapterError(f'image_info origin orientation is not a unit quaternion (norm {norm:.6f})')
    if abs(values['qx']) > 1e-6 or abs(values['qy']) > 1e-6:
        raise AdapterError('image_info origin is tilted; an FLS image grid turns about z only')
    yaw = 2.0 * math.atan2(values['qz'], values['qw'])
    try:
        return ImageGrid(resolution=values['resolution'], width=values['width'], height=values['height'],
                         origin_x=values['x'], origin_y=values['y'], origin_yaw=math.remainder(yaw, 2 * math.pi))
    except ValueError as exc:
        raise AdapterError(f'image_info: {exc}') from exc

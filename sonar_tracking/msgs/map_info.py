"""``/fls/image_info``: the pixel <-> metres mapping of ``/fls/image`` as a ``nav_msgs/MapMetaData``.

An FLS image is laid out as an OccupancyGrid (``sonar_tracking.core.fls.grid``), so MapMetaData
describes it exactly: ``resolution`` [m/pixel], ``width`` (columns, along the grid x axis),
``height`` (rows), ``origin`` the pose of the outer corner of pixel (0, 0) in the Image's
``header.frame_id``, and ``map_load_time`` = the Image's ``header.stamp``, by which a consumer
pairs the two (:class:`~sonar_tracking.msgs.pairing.StampPairer`). Works on rclpy messages and rosbags
dataclasses alike. Not re-exported by ``sonar_tracking.msgs`` (it needs the FLS grid): import
``sonar_tracking.msgs.map_info``.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.sector import MAX_CELLS
from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.image import image_to_array
from sonar_tracking.msgs.pointcloud import cloud_to_array
from sonar_tracking.msgs.stamps import ns_to_stamp
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['grid_to_map_info', 'map_info_to_grid', 'fls_image', 'fls_frame', 'MIN_RESOLUTION', 'MAX_RESOLUTION']

#: Physical bounds of an FLS image grid (a millimetre to 100 m pixels; at most MAX_CELLS pixels).
MIN_RESOLUTION, MAX_RESOLUTION = 1e-3, 100.0


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
    if not MIN_RESOLUTION <= values['resolution'] <= MAX_RESOLUTION:
        raise AdapterError(f'image_info resolution {values["resolution"]:g} m is outside [{MIN_RESOLUTION:g}, '
                           f'{MAX_RESOLUTION:g}] m')
    if values['width'] * values['height'] > MAX_CELLS:
        raise AdapterError(f'image_info says {values["width"]} x {values["height"]} pixels, more than {MAX_CELLS}')
    yaw = 2.0 * math.atan2(values['qz'], values['qw'])
    try:
        return ImageGrid(resolution=values['resolution'], width=int(values['width']), height=int(values['height']),
                         origin_x=values['x'], origin_y=values['y'], origin_yaw=math.remainder(yaw, 2 * math.pi))
    except ValueError as exc:
        raise AdapterError(f'image_info: {exc}') from exc


def fls_image(msg: Any, grid_shape: tuple[int, int]) -> np.ndarray:
    """The ``fls/image`` of a frame as a float32 array of its grid's shape, or AdapterError saying
    what is wrong with the message (encoding, size, NaN). Negative values are the tracker's to judge
    (``core.gpf.check_image``: round-off is read as 0, more is refused)."""
    image = image_to_array(msg)
    if image.dtype != np.float32:
        raise AdapterError(f'fls/image must be 32FC1 (processed intensity), got {image.dtype}')
    if image.shape != grid_shape:
        raise AdapterError(f'fls/image is {image.shape[0]} x {image.shape[1]} pixels but its image_info says '
                           f'{grid_shape[0]} x {grid_shape[1]}')
    bad = ~np.isfinite(image)
    if bad.any():
        raise AdapterError(f'fls/image has {int(bad.sum())} NaN or infinite pixels; no-data pixels must be 0')
    return image


def fls_frame(image_msg: Any, info_msg: Any, regions_msg: Any):
    """One FLS frame's three messages (``fls/image``, ``fls/image_info``, ``fls/regions``) as
    ``(grid, image, regions)``, or AdapterError saying which is unusable (regions need ``x, y``)."""
    grid = map_info_to_grid(info_msg)
    image = fls_image(image_msg, grid.shape)
    regions = cloud_to_array(regions_msg)
    names = set(regions.dtype.names or ())
    if not {'x', 'y'} <= names:
        raise AdapterError(f'/fls/regions need fields x and y; the cloud has {sorted(names)}')
    return grid, image, regions

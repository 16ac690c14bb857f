"""Where the pixels of an FLS image are: the pixel <-> metres mapping that travels with the image.

An FLS image (``/fls/image``) is stored in the layout of a ROS ``nav_msgs/OccupancyGrid``, so that
the standard ``nav_msgs/MapMetaData`` describes it exactly (``/fls/image_info``): pixel
``image[j, i]`` (row ``j``, column ``i``) has its centre at::

    (x, y) = origin + R(origin_yaw) @ ((i + 0.5) * resolution, (j + 0.5) * resolution)

in the image's frame (the Image header's ``frame_id``). Columns therefore run along the grid's x
axis and rows along its y axis. This is the mirror image of what a person expects on a screen
with row 0 at the top (an image viewer looks at a right-handed grid from below); the people's
picture is ``/sonar/fan``. The layout is chosen for machines: a pose (no reflection) maps pixels to
metres, which MapMetaData can carry and every ROS tool reads the same way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ['ImageGrid']


@dataclass(frozen=True)
class ImageGrid:
    """Pixel geometry of an FLS image in its frame (OccupancyGrid convention, see module docstring).

    Attributes
    ----------
    resolution : pixel size [m].
    width, height : number of columns (along the grid x axis) and rows (along the grid y axis).
    origin_x, origin_y, origin_yaw : pose of the outer corner of pixel (0, 0) in the image frame.
    """

    resolution: float
    width: int
    height: int
    origin_x: float
    origin_y: float
    origin_yaw: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f'grid resolution = {self.resolution} must be a finite number > 0')
        if int(self.width) != self.width or int(self.height) != self.height or self.width < 1 or self.height < 1:
            raise ValueError(f'grid size {self.width} x {self.height} must be positive integers')
        for name in ('origin_x', 'origin_y', 'origin_yaw'):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f'grid {name} = {getattr(self, name)} is not finite')

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(rows, columns) = (height, width)``."""
        return (self.height, self.width)

    def pixel_to_point(self, row: np.ndarray | float, col: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Frame coordinates ``(x, y)`` of fractional pixel positions (pixel centres at integers)."""
        u = (np.asarray(col, dtype=float) + 0.5) * self.resolution
        v = (np.asarray(row, dtype=float) + 0.5) * self.resolution
        c, s = math.cos(self.origin_yaw), math.sin(self.origin_yaw)
        return self.origin_x + c * u - s * v, self.origin_y + s * u + c * v

    def point_to_pixel(self, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Fractional ``(row, col)`` of frame points; round to get the pixel that contains them."""
        dx, dy = np.asarray(x, dtype=float) - self.origin_x, np.asarray(y, dtype=float) - self.origin_y
        c, s = math.cos(self.origin_yaw), math.sin(self.origin_yaw)
        u, v = c * dx + s * dy, -s * dx + c * dy
        return v / self.resolution - 0.5, u / self.resolution - 0.5

    def pixel_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Frame coordinates ``(x, y)`` of every pixel centre, each of shape ``(height, width)``."""
        rows, cols = np.indices(self.shape, dtype=float)
        return self.pixel_to_point(rows, cols)

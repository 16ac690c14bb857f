"""Image building: filtered sectors painted into a Cartesian image as the head sweeps (FLS paper §2).

Sectors are painted with :class:`~sonar_tracking.core.fan.PolarCanvas` at each sector's pose in
the image frame (the sensor frame for a static sonar, the world frame for a moving one), so an
image builds up beam by beam and every pixel keeps its latest value.

The canvas is axis-aligned in the image frame, its edges on multiples of the resolution, and it
covers the footprints of the sectors of the last two sweep times (``scan_time`` of the sector
geometry): for a static sonar that is the scanned sector, found as the head sweeps; for a moving
platform the canvas follows it. When the extent changes, the old pixels move over by whole
pixels (no resampling), and pixels newly covered stay unpainted until a beam reaches them.

:meth:`ImageBuilder.image` returns the image in the layout of :mod:`.grid` (OccupancyGrid order)
with NaN where nothing has been painted, and its :class:`~.grid.ImageGrid`.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import cast

import numpy as np

from sonar_tracking.core.config import Config, setting
from sonar_tracking.core.fan import PolarCanvas, fan_extent
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.sector import SectorGeometry

__all__ = ['ImageConfig', 'ImageBuilder', 'ImageTooLargeError', 'canvas_for', 'grid_image']


class ImageTooLargeError(ValueError):
    """The requested image would exceed ``image.max_side`` pixels."""


@dataclass(frozen=True)
class ImageConfig(Config):
    """Cartesian image settings."""

    resolution: float = setting(0.1, 'pixel size of the Cartesian image', unit='m', low=0.005, high=10.0,
                                read_only=True)
    publish: str = setting('sweep', 'emit the processed image when a sweep or when each sector completes',
                           choices=('sweep', 'sector'))
    max_side: int = setting(4096, 'largest image side accepted (guards memory against a tiny resolution)',
                            unit='px', low=16, high=32768)


def _snap(lo: float, hi: float, res: float) -> tuple[float, float]:
    """Widen ``[lo, hi]`` to multiples of ``res`` (a global pixel grid, so extents line up)."""
    return math.floor(lo / res + 1e-9) * res, math.ceil(hi / res - 1e-9) * res


class ImageBuilder:
    """Paints sectors into a Cartesian canvas whose extent follows the recent sector footprints."""

    def __init__(self, config: ImageConfig | None = None) -> None:
        self.config = config or ImageConfig()
        self.reset()

    def reset(self) -> None:
        """Drop the image and the footprint history."""
        self.canvas: PolarCanvas | None = None
        self._extent: tuple[float, float, float, float] | None = None
        self._footprints: deque[tuple[float, tuple[float, float, float, float]]] = deque()

    @staticmethod
    def footprint(geometry: SectorGeometry, pose: tuple[float, float, float]) -> tuple[float, float, float, float]:
        """Bounding box ``(x_min, x_max, y_min, y_max)`` in the image frame of a sector taken at ``pose``."""
        x0, x1, y0, y1 = fan_extent(geometry)
        px, py, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        xs = np.array([x0, x0, x1, x1])
        ys = np.array([y0, y1, y0, y1])
        wx, wy = px + c * xs - s * ys, py + s * xs + c * ys
        return float(wx.min()), float(wx.max()), float(wy.min()), float(wy.max())

    def paint(self, values: np.ndarray, geometry: SectorGeometry, pose: tuple[float, float, float],
              stamp: float) -> int:
        """Paint one block of beams taken at ``pose`` (image frame) at time ``stamp`` [s]; returns the
        number of pixels painted. Raises ImageTooLargeError if the extent needs too many pixels."""
        memory = 2.0 * geometry.scan_time
        self._footprints.append((stamp, self.footprint(geometry, pose)))
        while self._footprints and self._footprints[0][0] < stamp - memory:
            self._footprints.popleft()
        boxes = np.array([b for _, b in self._footprints])
        res = self.config.resolution
        x0, x1 = _snap(boxes[:, 0].min(), boxes[:, 1].max(), res)
        y0, y1 = _snap(boxes[:, 2].min(), boxes[:, 3].max(), res)
        extent = (x0, x1, y0, y1)
        if extent != self._extent:
            self._resize(extent)
        return cast(PolarCanvas, self.canvas).paint(values, geometry, pose)   # made by the first _resize

    def _resize(self, extent: tuple[float, float, float, float]) -> None:
        x0, x1, y0, y1 = extent
        res, side = self.config.resolution, self.config.max_side
        h, w = round((x1 - x0) / res), round((y1 - y0) / res)
        if max(h, w) > side:
            raise ImageTooLargeError(f'the image would be {h} x {w} pixels at {res:g} m, more than image.max_side '
                                     f'= {side}; raise image.resolution or image.max_side')
        new = PolarCanvas(x0, x1, y0, y1, res)
        old = self.canvas
        if old is not None:
            # Whole-pixel offset of the old canvas in the new one (both on the global grid).
            dr = int(round((new.x_max - old.x_max) / res))
            dc = int(round((new.y_max - old.y_max) / res))
            r0, r1 = max(0, dr), min(new.height, dr + old.height)
            c0, c1 = max(0, dc), min(new.width, dc + old.width)
            if r0 < r1 and c0 < c1:
                new.image[r0:r1, c0:c1] = old.image[r0 - dr:r1 - dr, c0 - dc:c1 - dc]
        self.canvas, self._extent = new, extent

    def image(self) -> tuple[np.ndarray, ImageGrid]:
        """The painted image in OccupancyGrid order (float32, NaN = not painted) and its grid."""
        if self.canvas is None:
            raise RuntimeError('no sector has been painted yet')
        return grid_image(self.canvas)


def grid_image(canvas: PolarCanvas) -> tuple[np.ndarray, ImageGrid]:
    """A canvas's image in the grid layout of :mod:`.grid` (a copy) and the grid describing it."""
    res = canvas.resolution
    # Canvas row r, column c is at (x_max - (r + .5) res, y_max - (c + .5) res); the grid wants
    # columns along +x and rows along +y.
    img = np.ascontiguousarray(canvas.image[::-1, ::-1].T)
    grid = ImageGrid(resolution=res, width=canvas.height, height=canvas.width,
                     origin_x=canvas.x_max - canvas.height * res, origin_y=canvas.y_max - canvas.width * res)
    return img, grid


def canvas_for(grid: ImageGrid, fill: float = np.nan) -> PolarCanvas:
    """An empty canvas whose :func:`grid_image` has exactly ``grid`` (axis-aligned grids only), to
    paint other data (raw sectors, truth) onto the pixels of a processed image."""
    if grid.origin_yaw != 0.0:
        raise ValueError('canvas_for needs an axis-aligned grid (origin_yaw = 0)')
    res = grid.resolution
    canvas = PolarCanvas(grid.origin_x, grid.origin_x + grid.width * res, grid.origin_y,
                         grid.origin_y + grid.height * res, res, fill=fill)
    if (canvas.height, canvas.width) != (grid.width, grid.height):  # rounding made an extra pixel
        canvas = PolarCanvas(grid.origin_x + 0.5 * res, grid.origin_x + grid.width * res, grid.origin_y + 0.5 * res,
                             grid.origin_y + grid.height * res, res, fill=fill)
    return canvas

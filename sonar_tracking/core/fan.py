"""Painting polar sectors into a Cartesian image (the sonar "fan").

One implementation serves the simulator's ``/sonar/fan`` picture and the FLS image building:
a :class:`PolarCanvas` covers a rectangle of a plane frame (the sensor frame, or the world frame
for a moving platform) at a fixed resolution; :meth:`PolarCanvas.paint` writes every pixel whose
centre falls inside a sector's beams and bins with that cell's value (nearest cell), leaving the
rest of the image as it was, so an image builds up as the head sweeps.

Image layout, as a person looks down on the plane: row 0 is the largest ``x`` (forward is up),
column 0 the largest ``y`` (left is left).
"""
from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from sonar_tracking.core.sector import SectorGeometry

__all__ = ['PolarCanvas', 'to_mono8', 'fan_extent']


def fan_extent(geometry: SectorGeometry, bearing_min: float | None = None, bearing_max: float | None = None,
               margin: float = 0.0) -> tuple[float, float, float, float]:
    """Bounding box ``(x_min, x_max, y_min, y_max)`` in the sensor frame of all bins of a bearing span.

    The span defaults to the geometry's own beams (half a beam beyond the first and last).
    """
    half = 0.5 * geometry.angle_increment
    a0 = geometry.angle_min - half if bearing_min is None else bearing_min
    a1 = geometry.angle_max + half if bearing_max is None else bearing_max
    r0, r1 = max(0.0, geometry.range_min - 0.5 * geometry.range_resolution), \
        geometry.range_max + 0.5 * geometry.range_resolution
    if a1 - a0 >= 2 * math.pi:
        return (-r1 - margin, r1 + margin, -r1 - margin, r1 + margin)
    angles = np.concatenate([np.linspace(a0, a1, 64),
                             [a for a in np.arange(-4, 5) * (math.pi / 2) if a0 <= a <= a1]])
    xs = np.concatenate([r0 * np.cos(angles), r1 * np.cos(angles)])
    ys = np.concatenate([r0 * np.sin(angles), r1 * np.sin(angles)])
    return (float(xs.min()) - margin, float(xs.max()) + margin, float(ys.min()) - margin, float(ys.max()) + margin)


class PolarCanvas:
    """A Cartesian image of ``[x_min, x_max] x [y_min, y_max]`` at ``resolution`` metres per pixel."""

    def __init__(self, x_min: float, x_max: float, y_min: float, y_max: float, resolution: float,
                 fill: float = np.nan, dtype: type = np.float32, cache_pixels: int = 4_000_000) -> None:
        if not (x_max > x_min and y_max > y_min and resolution > 0):
            raise ValueError('canvas needs x_max > x_min, y_max > y_min and resolution > 0')
        self.x_max, self.y_max, self.resolution = float(x_max), float(y_max), float(resolution)
        self.height = int(math.ceil((x_max - x_min) / resolution))
        self.width = int(math.ceil((y_max - y_min) / resolution))
        self.fill = fill
        self.image: np.ndarray = np.full((self.height, self.width), fill, dtype=dtype)
        # Pixel-centre coordinates in the canvas frame.
        self._x = self.x_max - (np.arange(self.height) + 0.5) * resolution
        self._y = self.y_max - (np.arange(self.width) + 0.5) * resolution
        # Pixel-to-cell maps by geometry and pose, least recently used first; at most
        # ``cache_pixels`` mapped pixels in all (16 bytes each), but always the latest map.
        self.cache_pixels = int(cache_pixels)
        self._maps: OrderedDict[tuple, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._cached = 0

    @classmethod
    def with_size(cls, extent: tuple[float, float, float, float], size_px: int, **kw) -> PolarCanvas:
        """A canvas of ``extent`` whose longer side has ``size_px`` pixels."""
        x0, x1, y0, y1 = extent
        return cls(x0, x1, y0, y1, max(x1 - x0, y1 - y0) / size_px, **kw)

    def clear(self) -> None:
        self.image.fill(self.fill)

    def pixel_of(self, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Fractional ``(row, col)`` of canvas-frame points (pixel centres at integers)."""
        res = self.resolution
        return (self.x_max - np.asarray(x)) / res - 0.5, (self.y_max - np.asarray(y)) / res - 0.5

    def point_of(self, row: np.ndarray | float, col: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Canvas-frame ``(x, y)`` of fractional pixel positions."""
        res = self.resolution
        return self.x_max - (np.asarray(row) + 0.5) * res, self.y_max - (np.asarray(col) + 0.5) * res

    def paint(self, values: np.ndarray, geometry: SectorGeometry,
              pose: tuple[float, float, float] = (0.0, 0.0, 0.0), hold_max: bool = False) -> int:
        """Write a sector ``(n_bins, n_beams)`` taken at ``pose`` (sensor pose in the canvas frame).

        With ``hold_max`` a pixel keeps the largest value painted on it so far (a track picture).
        Returns the number of pixels painted. The pixel-to-cell map of a geometry and pose is
        cached, so painting the same geometry again (a fixed sonar) only copies values.
        """
        pixels, cells = self._cell_map(geometry, pose)
        if pixels.size == 0:
            return 0
        flat = self.image.reshape(-1)
        new = np.asarray(values).reshape(-1)[cells]
        flat[pixels] = np.fmax(flat[pixels], new) if hold_max else new
        return int(pixels.size)

    def _cell_map(self, geometry: SectorGeometry,
                  pose: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
        """Flat image indices of the pixels a sector covers and the flat sector cell of each (cached)."""
        key = (geometry.angle_min, geometry.angle_increment, geometry.n_beams, geometry.range_min,
               geometry.range_max, geometry.n_bins, float(pose[0]), float(pose[1]), float(pose[2]))
        hit = self._maps.get(key)
        if hit is not None:
            self._maps.move_to_end(key)
            return hit
        pixels, cells = self._compute_cell_map(geometry, pose)
        self._maps[key] = (pixels, cells)
        self._cached += pixels.size
        while self._cached > self.cache_pixels and len(self._maps) > 1:  # bounded memory
            _, (old, _) = self._maps.popitem(last=False)
            self._cached -= old.size
        return pixels, cells

    def _compute_cell_map(self, geometry: SectorGeometry,
                          pose: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
        """Nearest sector cell of every pixel centre inside the sector's beams and bins."""
        empty = np.empty(0, dtype=np.intp)
        px, py, yaw = pose
        x0, x1, y0, y1 = fan_extent(geometry)
        c, s = math.cos(yaw), math.sin(yaw)
        # Bounding box of the sector in the canvas frame, then the pixel window covering it.
        corners = np.array([[x0, y0], [x0, y1], [x1, y0], [x1, y1]])
        wx = px + corners[:, 0] * c - corners[:, 1] * s
        wy = py + corners[:, 0] * s + corners[:, 1] * c
        (r_lo, r_hi), (c_lo, c_hi) = self.pixel_of(np.array([wx.max(), wx.min()]), np.array([wy.max(), wy.min()]))
        r0, r1 = max(0, int(math.floor(r_lo))), min(self.height, int(math.ceil(r_hi)) + 1)
        c0, c1 = max(0, int(math.floor(c_lo))), min(self.width, int(math.ceil(c_hi)) + 1)
        if r0 >= r1 or c0 >= c1:
            return empty, empty
        dx = self._x[r0:r1, None] - px
        dy = self._y[None, c0:c1] - py
        xs, ys = dx * c + dy * s, -dx * s + dy * c  # into the sensor frame
        rng = np.hypot(xs, ys)
        brg = np.arctan2(ys, xs)
        inc = geometry.angle_increment
        # Bearing offset from column 0 in [-inc/2, 2 pi - inc/2): sectors may span up to 360 deg.
        j = np.rint((np.remainder(brg - geometry.angle_min + 0.5 * inc, 2 * math.pi) - 0.5 * inc) / inc)
        dr = geometry.range_resolution if geometry.n_bins > 1 else max(geometry.range_min, 1.0)
        i = np.rint((rng - geometry.range_min) / dr)
        ok = (j >= 0) & (j < geometry.n_beams) & (i >= 0) & (i < geometry.n_bins)
        rows, cols = np.nonzero(ok)
        pixels = (rows + r0) * self.width + (cols + c0)
        cells = i[ok].astype(np.intp) * geometry.n_beams + j[ok].astype(np.intp)
        return pixels.astype(np.intp), cells


def to_mono8(image: np.ndarray, dynamic_range_db: float = 30.0, floor_percentile: float = 50.0) -> np.ndarray:
    """Log-scale an intensity image to uint8 for people: the ``floor_percentile`` of painted pixels
    maps to black, ``dynamic_range_db`` above it to white; unpainted (NaN) pixels are black."""
    out = np.zeros(image.shape, dtype=np.uint8)
    painted = np.isfinite(image) & (image > 0)
    if not painted.any():
        return out
    db = 10.0 * np.log10(image[painted])
    lo = np.percentile(db, floor_percentile)
    out[painted] = np.clip((db - lo) * (255.0 / dynamic_range_db), 0, 255).astype(np.uint8)
    return out

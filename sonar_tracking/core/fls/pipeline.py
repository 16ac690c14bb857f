"""The FLS front end (paper §2-§3.1) as one component: sectors in, processed images and regions out.

:class:`FlsProcessor` wires the parts together, as the ``fls_features`` node and the evaluation
tools use them::

    sector --check, intensity--> PolarSweepFilter --blocks--> ImageBuilder --image--> grow_regions
           --labels--> structure rejection --> region_features --> REGION_DTYPE records (x, y in the
           image frame; range, bearing from the sonar's latest pose)

The sector's values are turned into linear echo amplitude by ``intensity``
(:func:`sonar_tracking.core.intensity.condition`: 8-bit dB counts, power or display values, noise
floor, near-range blanking, maximum range); the default takes the simulator's linear amplitude as
it is. Static structure (``structure``, :mod:`sonar_tracking.core.structure`) is rejected per
region: regions too long, too wide, too large or elongated, and regions lying on pixels that echo
persistently; their pixels, and every pixel above the background level on a persistent cell of the
background, are masked out of the frame's image as no data (0), so a tracker reading the image
(the GPF) finds nothing there and a track that sat on structure before the background knew it
ends. With ``structure.warmup`` no region comes out until the background has learnt for
``min_echo_time``. The persistent-echo background is a grid in the image frame (the sensor frame
for a static sonar, the world frame for a moving one) that learns once per completed sweep from
the pixels above the growth level ``segment.grow_db``, so each pixel is one look per sweep.

A frame (:class:`FlsFrame`) is emitted when a sweep completes (:mod:`.sweep`), or after every
sector with ``image.publish = 'sector'``. Its image is the filtered, range-normalised intensity
(1 = background) with 0 where there is no data, in the layout of :mod:`.grid`; regions and
features refer to exactly that array, so a consumer (the GPF tracker) can compute the same
features on it.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from sonar_tracking.core.config import Config, ConfigError
from sonar_tracking.core.fls.features import FeatureConfig, region_features
from sonar_tracking.core.fls.filters import FilterConfig, PolarSweepFilter
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.fls.image import ImageBuilder, ImageConfig, ImageTooLargeError
from sonar_tracking.core.fls.segmentation import SegmentConfig, cells_per_pixel, grow_regions, relabel
from sonar_tracking.core.fls.sweep import SweepTracker
from sonar_tracking.core.intensity import IntensityConfig, condition
from sonar_tracking.core.records import FEATURE_NAMES, REGION_DTYPE
from sonar_tracking.core.sector import GeometryError, SectorError, SectorGeometry
from sonar_tracking.core.sector import check_sector as sector_rule
from sonar_tracking.core.structure import (
    GridBackground,
    StructureConfig,
    WarmUp,
    echo_shapes,
    is_structure_shape,
    vetoed_groups,
)
from sonar_tracking.core.timeline import check_forward

__all__ = ['FlsConfig', 'FlsFrame', 'FlsProcessor', 'FlsInputError', 'check_sector', 'regions_to_records']


class FlsInputError(ValueError):
    """A sector cannot be used; the message says what is wrong with it."""


@dataclass(frozen=True)
class FlsConfig(Config):
    """All settings of the FLS front end, grouped by stage (dotted names: ``segment.seed_db``)."""

    intensity: IntensityConfig = dataclasses.field(default_factory=IntensityConfig)
    image: ImageConfig = dataclasses.field(default_factory=ImageConfig)
    filter: FilterConfig = dataclasses.field(default_factory=FilterConfig)
    segment: SegmentConfig = dataclasses.field(default_factory=SegmentConfig)
    structure: StructureConfig = dataclasses.field(default_factory=StructureConfig)
    features: FeatureConfig = dataclasses.field(default_factory=FeatureConfig)

    def validate(self) -> None:
        reach = self.intensity.max_range
        side = math.ceil(2.0 * reach / self.image.resolution) if reach else 0
        if side > self.image.max_side:
            raise ConfigError(f'intensity.max_range = {reach:g} m needs an image of up to {side} pixels a side at '
                              f'image.resolution = {self.image.resolution:g} m, more than image.max_side = '
                              f'{self.image.max_side}; raise image.resolution or image.max_side, or lower max_range')


@dataclass(eq=False)
class FlsFrame:
    """One processed image with its regions.

    ``image`` float32 in the grid layout (0 = no data), ``labels`` int32 (0 = no region, region
    ``k`` is ``regions[k - 1]``), ``regions`` REGION_DTYPE, ``sensor_pose`` the sonar's pose in
    the image frame at ``stamp`` (the last sector in the image), ``timings`` seconds per stage.
    """

    stamp: float
    image: np.ndarray
    grid: ImageGrid
    labels: np.ndarray
    regions: np.ndarray
    sensor_pose: tuple[float, float, float]
    sectors: int
    background_db: float
    timings: dict[str, float] = field(default_factory=dict)
    structure: int = 0   # regions dropped as static structure in this frame


def check_sector(amplitudes: np.ndarray, geometry: SectorGeometry,
                 intensity: IntensityConfig | None = None) -> tuple[np.ndarray, SectorGeometry]:
    """The sector as float32 linear amplitude (bins x beams) and its geometry, decoded and gated by
    ``intensity`` (``max_range`` may cut bins), or FlsInputError saying what is wrong with it (the
    rule of every sector consumer, :func:`sonar_tracking.core.sector.check_sector`)."""
    intensity = intensity or IntensityConfig()
    a = np.asarray(amplitudes)
    if a.ndim != 2:
        raise FlsInputError(f'sector must be a 2-D array (range bins x beams), got shape {a.shape}')
    if a.size == 0:
        raise FlsInputError(f'sector is empty (shape {a.shape})')
    try:
        a = sector_rule(a, geometry, intensity.coding)
    except (SectorError, GeometryError) as exc:
        raise FlsInputError(str(exc)) from None
    amplitude, geometry = condition(a, geometry, intensity)
    return amplitude.astype(np.float32), geometry


def regions_to_records(image: np.ndarray, labels: np.ndarray, n: int, grid: ImageGrid,
                       sensor_pose: tuple[float, float, float], config: FeatureConfig) -> np.ndarray:
    """REGION_DTYPE records: intensity-weighted centroid (x, y in the image frame), its range and
    bearing from the sonar at ``sensor_pose``, and features f01..f30 (:func:`region_features`)."""
    rec = np.zeros(n, REGION_DTYPE)
    if n == 0:
        return rec
    rec['region_id'] = np.arange(1, n + 1)
    idx = np.flatnonzero(labels)
    own = labels.ravel()[idx]
    rows, cols = np.divmod(idx, labels.shape[1])
    w = np.nan_to_num(image.ravel()[idx].astype(np.float64), nan=0.0)
    wsum = np.bincount(own, weights=w, minlength=n + 1)[1:]
    wsum = np.where(wsum > 0, wsum, 1.0)
    r = np.bincount(own, weights=w * rows, minlength=n + 1)[1:] / wsum
    c = np.bincount(own, weights=w * cols, minlength=n + 1)[1:] / wsum
    x, y = grid.pixel_to_point(r, c)
    px, py, yaw = sensor_pose
    rec['x'], rec['y'] = x, y
    rec['range'] = np.hypot(x - px, y - py)
    rec['bearing'] = np.remainder(np.arctan2(y - py, x - px) - yaw + math.pi, 2 * math.pi) - math.pi
    feats = region_features(image, labels, n, config)
    for k, name in enumerate(FEATURE_NAMES):
        rec[name] = feats[:, k]
    return rec


class FlsProcessor:
    """Sectors in (with their geometry, pose in the image frame and time), frames out."""

    def __init__(self, config: FlsConfig | None = None) -> None:
        self.config = config or FlsConfig()
        self.filter = PolarSweepFilter(self.config.filter)
        self.builder = ImageBuilder(self.config.image)
        self.sweep = SweepTracker()
        self.background: GridBackground | None = None
        self.warmup = WarmUp()
        self.resets = 0
        self._weight_key: tuple | None = None
        self._weight: np.ndarray | None = None
        self._clear()

    def _clear(self) -> None:
        self._pending = 0
        self._last_stamp = -math.inf
        self._pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._geometry: SectorGeometry | None = None
        self._t_sectors = 0.0

    def reset(self) -> None:
        """Start again from an empty image (a new recording, or the geometry changed)."""
        self.filter.reset()
        self.builder.reset()
        self.sweep.reset()
        self.background = None
        self.warmup.reset()
        self.resets += 1
        self._clear()

    def reconfigure(self, config: FlsConfig) -> None:
        """Apply new settings; the image is kept unless its resolution or the filter changed."""
        old, self.config = self.config, config
        if config.filter != old.filter or config.image.resolution != old.image.resolution:
            self.filter = PolarSweepFilter(config.filter)
            self.builder = ImageBuilder(config.image)
            self.reset()
        else:
            self.builder.config = config.image
        if config.structure != old.structure:
            self.background = None
            self.warmup.reset()

    def add_sector(self, amplitudes: np.ndarray, geometry: SectorGeometry,
                   pose: tuple[float, float, float] = (0.0, 0.0, 0.0), stamp: float = 0.0) -> list[FlsFrame]:
        """Process one sector (bins x beams, linear intensity) taken at ``pose`` (image frame) at
        ``stamp`` [s]; returns the frames it completes (none, one, or the previous sweep's and this
        sector's). Raises FlsInputError for a sector that cannot be used, and
        :class:`~sonar_tracking.core.timeline.TimeWentBack` for one stamped before the previous
        sector (:meth:`reset` first to start again from it); nothing is changed."""
        t0 = time.perf_counter()
        a, geometry = check_sector(amplitudes, geometry, self.config.intensity)
        if not all(map(math.isfinite, pose)):
            raise FlsInputError(f'sonar pose {pose} is not finite')
        check_forward('sector', stamp, self._last_stamp)
        frames: list[FlsFrame] = []
        step = self.sweep.update(geometry)
        if step.starts and self._pending:
            frames.append(self._emit(sweep_end=True))
        try:
            for block in self.filter.add(a, geometry, pose):
                self.builder.paint(block.values, block.geometry, block.pose, stamp)
        except ImageTooLargeError as exc:
            self.reset()
            raise FlsInputError(str(exc)) from None
        self._pending += 1
        self._last_stamp, self._geometry = stamp, geometry
        self._pose = cast(tuple[float, float, float], tuple(map(float, pose)))
        self._t_sectors += time.perf_counter() - t0
        if step.ends or self.config.image.publish == 'sector':
            frames.append(self._emit(sweep_end=step.ends))
        return frames

    def flush(self) -> FlsFrame | None:
        """The frame of the sectors painted since the last one, if any (e.g. at the end of a log)."""
        return self._emit() if self._pending else None

    def _last_geometry(self) -> SectorGeometry:
        """The geometry of the last sector painted (there is one before any frame is made)."""
        if self._geometry is None:
            raise RuntimeError('no sector has been painted yet')
        return self._geometry

    def _grid_background(self) -> GridBackground:
        """The world-grid background of the persistence veto (made at the first structure check)."""
        if self.background is None:
            raise RuntimeError('the structure background has not been made yet')
        return self.background

    def _cell_weight(self, grid: ImageGrid) -> np.ndarray:
        g = self._last_geometry()
        key = (grid, self._pose, g.angle_increment, g.range_resolution)
        weight = self._weight
        if key != self._weight_key or weight is None:
            weight = self._weight = cells_per_pixel(grid, self._pose, g.angle_increment, g.range_resolution)
            self._weight_key = key
        return weight

    def _emit(self, sweep_end: bool = True) -> FlsFrame:
        c = self.config
        t0 = time.perf_counter()
        raw, grid = self.builder.image()
        image = np.nan_to_num(raw, nan=0.0)
        t1 = time.perf_counter()
        labels, n = grow_regions(image, c.segment, grid.resolution, self._cell_weight(grid))
        dropped = 0
        static = None
        if c.structure.enabled:
            static = labels > 0
            labels, kept = self._reject_structure(image, raw, grid, labels, n, sweep_end)
            static &= labels == 0
            dropped, n = n - kept, kept
        t2 = time.perf_counter()
        regions = regions_to_records(image, labels, n, grid, self._pose, c.features)
        if static is not None and self.background is not None:
            static |= self._persistent_pixels(image, grid)
        if static is not None and static.any():
            # Structure is masked out of the image too, as no data: a tracker that follows image
            # evidence (the GPF) must not find it there either.
            image = np.where(static, np.float32(0.0), image)
        t3 = time.perf_counter()
        level = self.filter.level
        background_db = float(10 * np.log10(np.median(level))) if level is not None else math.nan
        frame = FlsFrame(stamp=self._last_stamp, image=image, grid=grid, labels=labels, regions=regions,
                         sensor_pose=self._pose, sectors=self._pending, background_db=background_db,
                         timings={'filter_paint': self._t_sectors, 'image': t1 - t0, 'segment': t2 - t1,
                                  'features': t3 - t2}, structure=dropped)
        self._pending, self._t_sectors = 0, 0.0
        return frame

    def _reject_structure(self, image: np.ndarray, raw: np.ndarray, grid: ImageGrid, labels: np.ndarray, n: int,
                          learn: bool) -> tuple[np.ndarray, int]:
        """Regions that are not static structure, relabelled (see :mod:`sonar_tracking.core.structure`);
        at the end of a sweep the background then learns this image."""
        sc = self.config.structure
        res = grid.resolution
        structure = np.zeros(n, bool)
        rows, cols = np.nonzero(labels)
        own = labels[rows, cols] - 1
        x, y = grid.pixel_to_point(rows, cols)
        if sc.shape_gates and n:
            var = res * res / 12.0
            length, width, area = echo_shapes(x, y, own, n, var, 0.0, var, res * res)
            structure |= is_structure_shape(length, width, area, sc)
        if sc.persistence_veto:
            if self.background is None:
                g = self._last_geometry()
                sensor_cell = max(g.range_resolution, 0.5 * (g.range_min + g.range_max) * g.angle_increment)
                self.background = GridBackground(sc, sc.world_cell or max(res, sensor_cell))
            t = self._last_stamp
            if n:
                on = self.background.persistent(x, y, t)
                structure |= vetoed_groups(own, n, on, sc.veto_fraction)
            if learn:
                self._learn(image, raw, grid, t)
        if self.warmup.holding(self._last_stamp, sc):
            structure[:] = True          # the background is too young to tell structure from targets
        keep = np.concatenate([[False], ~structure])
        return relabel(labels, keep)

    def _persistent_pixels(self, image: np.ndarray, grid: ImageGrid) -> np.ndarray:
        """Pixels above the background level that lie on persistent cells of the background (the
        parts of a wall or seabed band that no region covers, and structure tracks may sit on)."""
        out = np.zeros(image.shape, bool)
        rows, cols = np.nonzero(image > 1.0)
        if rows.size:
            x, y = grid.pixel_to_point(rows, cols)
            on = self._grid_background().persistent(x, y, self._last_stamp)
            out[rows[on], cols[on]] = True
        return out

    def _learn(self, image: np.ndarray, raw: np.ndarray, grid: ImageGrid, t: float) -> None:
        """One look of the background at every painted pixel; echo where above the growth level."""
        level = np.float32(10.0 ** (self.config.segment.grow_db / 10.0))
        g = self._last_geometry()
        reach = g.range_max + g.range_resolution + grid.resolution
        if grid.origin_yaw == 0.0:  # the builder's images: x along columns, y along rows
            xs, _ = grid.pixel_to_point(np.zeros(grid.width), np.arange(grid.width))
            _, ys = grid.pixel_to_point(np.arange(grid.height), np.zeros(grid.height))
            self._grid_background().update_raster(xs, ys, np.isfinite(raw), image > level, self._pose[:2], reach, t)
        else:
            rows, cols = np.nonzero(np.isfinite(raw))
            x, y = grid.pixel_to_point(rows, cols)
            self._grid_background().update([(x, y, image[rows, cols] > level)], self._pose[:2], reach, t)

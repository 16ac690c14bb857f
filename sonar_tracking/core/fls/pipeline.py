"""The FLS front end (paper §2-§3.1) as one component: sectors in, processed images and regions out.

:class:`FlsProcessor` wires the parts together, as the ``fls_features`` node and the evaluation
tools use them::

    sector --check--> PolarSweepFilter --blocks--> ImageBuilder --image--> grow_regions --labels-->
           region_features --> REGION_DTYPE records (x, y in the image frame; range, bearing from
           the sonar's latest pose)

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

import numpy as np

from ..config import Config
from ..records import FEATURE_NAMES, REGION_DTYPE
from ..sector import SectorGeometry
from .features import FeatureConfig, region_features
from .filters import FilterConfig, PolarSweepFilter
from .grid import ImageGrid
from .image import ImageBuilder, ImageConfig, ImageTooLargeError
from .segmentation import SegmentConfig, cells_per_pixel, grow_regions
from .sweep import SweepTracker

__all__ = ['FlsConfig', 'FlsFrame', 'FlsProcessor', 'FlsInputError', 'check_sector', 'regions_to_records']


class FlsInputError(ValueError):
    """A sector cannot be used; the message says what is wrong with it."""


@dataclass(frozen=True)
class FlsConfig(Config):
    """All settings of the FLS front end, grouped by stage (dotted names: ``segment.seed_db``)."""

    image: ImageConfig = dataclasses.field(default_factory=ImageConfig)
    filter: FilterConfig = dataclasses.field(default_factory=FilterConfig)
    segment: SegmentConfig = dataclasses.field(default_factory=SegmentConfig)
    features: FeatureConfig = dataclasses.field(default_factory=FeatureConfig)


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


def check_sector(amplitudes: np.ndarray, geometry: SectorGeometry) -> np.ndarray:
    """The sector as float32 (bins x beams), or FlsInputError saying what is wrong with it."""
    a = np.asarray(amplitudes)
    if a.ndim != 2:
        raise FlsInputError(f'sector must be a 2-D array (range bins x beams), got shape {a.shape}')
    if a.size == 0:
        raise FlsInputError(f'sector is empty (shape {a.shape})')
    if a.shape != geometry.shape:
        raise FlsInputError(f'sector is {a.shape[0]} bins x {a.shape[1]} beams but its geometry says '
                            f'{geometry.n_bins} x {geometry.n_beams}')
    if a.dtype.kind not in 'uif':
        raise FlsInputError(f'sector has dtype {a.dtype}; expected numbers (linear echo intensity)')
    a = a.astype(np.float32, copy=False)
    bad = ~np.isfinite(a)
    if bad.any():
        raise FlsInputError(f'sector has {int(bad.sum())} NaN or infinite values; the driver must send '
                            'finite intensities')
    if (a < 0).any():
        raise FlsInputError(f'sector has {int((a < 0).sum())} negative values; expected linear echo '
                            'intensity >= 0')
    if not a.any():
        raise FlsInputError('sector is all zero (no echo at all: transducer muted, gain 0 or a driver fault)')
    return a


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
        self.resets = 0
        self._weight_key: tuple | None = None
        self._weight: np.ndarray | None = None
        self._clear()

    def _clear(self) -> None:
        self._pending = 0
        self._last_stamp = -math.inf
        self._pose = (0.0, 0.0, 0.0)
        self._geometry: SectorGeometry | None = None
        self._t_sectors = 0.0

    def reset(self) -> None:
        """Start again from an empty image (after time went backwards or the geometry changed)."""
        self.filter.reset()
        self.builder.reset()
        self.sweep.reset()
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

    def add_sector(self, amplitudes: np.ndarray, geometry: SectorGeometry,
                   pose: tuple[float, float, float] = (0.0, 0.0, 0.0), stamp: float = 0.0) -> list[FlsFrame]:
        """Process one sector (bins x beams, linear intensity) taken at ``pose`` (image frame) at
        ``stamp`` [s]; returns the frames it completes (none, one, or the previous sweep's and this
        sector's). Raises FlsInputError for a sector that cannot be used (nothing is changed)."""
        t0 = time.perf_counter()
        a = check_sector(amplitudes, geometry)
        if not all(map(math.isfinite, pose)):
            raise FlsInputError(f'sonar pose {pose} is not finite')
        if stamp < self._last_stamp:
            self.reset()
        frames: list[FlsFrame] = []
        step = self.sweep.update(geometry)
        if step.starts and self._pending:
            frames.append(self._emit())
        try:
            for block in self.filter.add(a, geometry, pose):
                self.builder.paint(block.values, block.geometry, block.pose, stamp)
        except ImageTooLargeError as exc:
            self.reset()
            raise FlsInputError(str(exc)) from None
        self._pending += 1
        self._last_stamp, self._pose, self._geometry = stamp, tuple(map(float, pose)), geometry
        self._t_sectors += time.perf_counter() - t0
        if step.ends or self.config.image.publish == 'sector':
            frames.append(self._emit())
        return frames

    def flush(self) -> FlsFrame | None:
        """The frame of the sectors painted since the last one, if any (e.g. at the end of a log)."""
        return self._emit() if self._pending else None

    def _cell_weight(self, grid: ImageGrid) -> np.ndarray:
        g = self._geometry
        key = (grid, self._pose, g.angle_increment, g.range_resolution)
        if key != self._weight_key:
            self._weight = cells_per_pixel(grid, self._pose, g.angle_increment, g.range_resolution)
            self._weight_key = key
        return self._weight

    def _emit(self) -> FlsFrame:
        c = self.config
        t0 = time.perf_counter()
        raw, grid = self.builder.image()
        image = np.nan_to_num(raw, nan=0.0)
        t1 = time.perf_counter()
        labels, n = grow_regions(image, c.segment, grid.resolution, self._cell_weight(grid))
        t2 = time.perf_counter()
        regions = regions_to_records(image, labels, n, grid, self._pose, c.features)
        t3 = time.perf_counter()
        level = self.filter.level
        background_db = float(10 * np.log10(np.median(level))) if level is not None else math.nan
        frame = FlsFrame(stamp=self._last_stamp, image=image, grid=grid, labels=labels, regions=regions,
                         sensor_pose=self._pose, sectors=self._pending, background_db=background_db,
                         timings={'filter_paint': self._t_sectors, 'image': t1 - t0, 'segment': t2 - t1,
                                  'features': t3 - t2})
        self._pending, self._t_sectors = 0, 0.0
        return frame

"""Polar geometry of a sonar sector image.

A sector is an image whose rows are range bins (row 0 nearest) and whose columns are beams in
increasing bearing (DESIGN §4). Bearings are counter-clockwise from the sensor's x axis (REP-103).
The geometry travels on ``/sonar/sector_info`` as a ``sensor_msgs/LaserScan`` with the same
header as the image; ``sonar_tracking.msgs.sector`` converts between the two.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ['SectorGeometry', 'GeometryError', 'SectorError', 'check_sector', 'MAX_RANGE', 'MAX_BEAMS_PER_TURN',
           'MAX_CELLS']

#: Physical bounds every consumer applies before it allocates anything for a sector: no sonar
#: reaches beyond 100 km, forms more than 65536 beams in a turn, or sends 2^25 cells at once.
MAX_RANGE = 1e5
MAX_BEAMS_PER_TURN = 65536
MAX_CELLS = 2 ** 25


class GeometryError(ValueError):
    """Sector geometry is inconsistent (bad counts, non-finite values, wrong order) or beyond the
    physical bounds (``MAX_RANGE``, ``MAX_BEAMS_PER_TURN``, ``MAX_CELLS``)."""


class SectorError(ValueError):
    """Sector values cannot be echo intensities (NaN, infinite or negative)."""


@dataclass(frozen=True)
class SectorGeometry:
    """Geometry of one sector: beam bearings and range-bin centres.

    Attributes
    ----------
    angle_min : bearing of column 0 [rad].
    angle_increment : bearing step between columns [rad], > 0.
    n_beams : number of columns (beams).
    range_min, range_max : centres of the first and last range bin [m].
    n_bins : number of rows (range bins).
    ping_period : time between the pings of consecutive columns [s] (LaserScan
        ``time_increment``); negative when the head swept toward decreasing bearing, so column 0
        was pinged last; 0 when all beams are formed at once.
    scan_time : time between two sectors [s].
    """

    angle_min: float
    angle_increment: float
    n_beams: int
    range_min: float
    range_max: float
    n_bins: int
    ping_period: float = 0.0
    scan_time: float = 0.0

    def __post_init__(self) -> None:
        for name in ('angle_min', 'angle_increment', 'range_min', 'range_max', 'ping_period', 'scan_time'):
            if not math.isfinite(getattr(self, name)):
                raise GeometryError(f'{name} = {getattr(self, name)} is not finite')
        if int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise GeometryError(f'n_beams = {self.n_beams} must be a positive integer')
        if int(self.n_bins) != self.n_bins or self.n_bins < 1:
            raise GeometryError(f'n_bins = {self.n_bins} must be a positive integer')
        if self.angle_increment <= 0.0:
            raise GeometryError(f'angle_increment = {self.angle_increment} must be > 0 '
                                '(columns are beams in increasing bearing)')
        if self.range_min < 0.0 or self.range_max < self.range_min:
            raise GeometryError(f'ranges must satisfy 0 <= range_min <= range_max, got '
                                f'{self.range_min}, {self.range_max}')
        if self.n_bins > 1 and self.range_max == self.range_min:
            raise GeometryError(f'{self.n_bins} range bins need range_max > range_min')
        if self.scan_time < 0.0:
            raise GeometryError(f'scan_time = {self.scan_time} must be >= 0')
        if self.range_max > MAX_RANGE:
            raise GeometryError(f'range_max = {self.range_max:g} m is beyond any sonar (at most {MAX_RANGE:g} m)')
        if self.angle_increment < 2.0 * math.pi / MAX_BEAMS_PER_TURN:
            raise GeometryError(f'angle_increment = {self.angle_increment:g} rad is finer than '
                                f'{MAX_BEAMS_PER_TURN} beams per turn')
        if (self.n_beams - 1) * self.angle_increment > 2.0 * math.pi * (1.0 + 1e-6):
            raise GeometryError(f'{self.n_beams} beams of {self.angle_increment:g} rad span more than a full turn')
        if self.n_beams * self.n_bins > MAX_CELLS:
            raise GeometryError(f'{self.n_bins} bins x {self.n_beams} beams is more than {MAX_CELLS} cells')

    @property
    def angle_max(self) -> float:
        """Bearing of the last column [rad]."""
        return self.angle_min + (self.n_beams - 1) * self.angle_increment

    @property
    def range_resolution(self) -> float:
        """Distance between two range-bin centres [m] (0 for a single bin)."""
        return (self.range_max - self.range_min) / (self.n_bins - 1) if self.n_bins > 1 else 0.0

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(n_bins, n_beams)``."""
        return (self.n_bins, self.n_beams)

    def bearings(self) -> np.ndarray:
        """Bearing of every column [rad], shape (n_beams,)."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams)

    def ranges(self) -> np.ndarray:
        """Centre range of every row [m], shape (n_bins,)."""
        return self.range_min + self.range_resolution * np.arange(self.n_bins)

    def strongest_returns(self, amplitudes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Range and amplitude of the strongest bin of each beam (the LaserScan payload).

        Returns ``(ranges, intensities)``, each of shape (n_beams,).
        """
        a = np.asarray(amplitudes)
        if a.shape != self.shape:
            raise GeometryError(f'amplitudes have shape {a.shape}, geometry says {self.shape}')
        idx = np.argmax(a, axis=0)
        return self.ranges()[idx], a[idx, np.arange(self.n_beams)].astype(np.float64)


def check_sector(values: np.ndarray, geometry: SectorGeometry, coding: str = 'linear_amplitude') -> np.ndarray:
    """The sector's values as an array of the geometry's shape, or SectorError / GeometryError saying
    what is wrong: the one rule of every sector consumer (detector, FLS front end, importer).

    NaN and infinite values are refused, and so are negative ones unless ``coding`` is ``db``
    (:mod:`sonar_tracking.core.intensity`); an all-zero sector is valid (nothing was seen: open
    water, blanked, below the gain floor).
    """
    a = np.asarray(values)
    if a.shape != geometry.shape:
        raise GeometryError(f'sector is {a.shape} but its geometry says {geometry.n_bins} bins x '
                            f'{geometry.n_beams} beams')
    if a.dtype.kind not in 'uif':
        raise SectorError(f'sector has dtype {a.dtype}; expected numbers (echo intensity)')
    if a.dtype.kind == 'f':
        bad = ~np.isfinite(a)
        if bad.any():
            raise SectorError(f'sector has {int(bad.sum())} NaN or infinite values')
    if a.dtype.kind != 'u' and coding != 'db':
        negative = a < 0
        if negative.any():
            raise SectorError(f'sector has {int(negative.sum())} negative values; echo intensity is >= 0')
    return a

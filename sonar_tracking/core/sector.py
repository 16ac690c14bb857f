"""Polar geometry of a sonar sector image.

A sector is an image whose rows are range bins (row 0 nearest) and whose columns are beams in
increasing bearing (DESIGN §4). Bearings are counter-clockwise from the sensor's x axis (REP-103).
The geometry travels on ``/sonar/sector_info`` as a ``sensor_msgs/LaserScan`` with the same
header as the image; ``msg_adapters.sector`` converts between the two.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ['SectorGeometry', 'GeometryError']


class GeometryError(ValueError):
    """Sector geometry is inconsistent (bad counts, non-finite values, wrong order)."""


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

"""Sensor coverage: the world-frame region a sonar can see, so tracks that leave it end.

A scanning or imaging sonar sees an annular sector: ranges ``[range_min, range_max]`` and
bearings ``[bearing_min, bearing_max]`` (sensor frame, REP-103, counter-clockwise from the
sensor's x axis) around the sensor at ``origin`` with heading ``yaw`` in the world frame.
IPDA keeps a track that nothing can detect only through its existence chain (eq. 24 with
``P_D = 0`` outside the window would never end it); the tracker ends such tracks after
``track.max_time_outside``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import TrackingInputError

__all__ = ['Coverage']


@dataclass(frozen=True)
class Coverage:
    """Annular sector seen by the sensor (lengths in m, angles in rad).

    ``bearing_max - bearing_min >= 2 pi`` means all bearings.
    """

    origin: tuple[float, float]
    yaw: float
    bearing_min: float
    bearing_max: float
    range_max: float
    range_min: float = 0.0

    def __post_init__(self) -> None:
        vals = (*self.origin, self.yaw, self.bearing_min, self.bearing_max, self.range_max, self.range_min)
        if len(self.origin) != 2 or not all(math.isfinite(v) for v in vals):
            raise TrackingInputError(f'coverage {self} must hold a 2-D origin and finite values')
        if not 0.0 <= self.range_min < self.range_max:
            raise TrackingInputError(f'coverage ranges {self.range_min}..{self.range_max} must satisfy 0 <= min < max')
        if self.bearing_max < self.bearing_min:
            raise TrackingInputError(f'coverage bearing_max {self.bearing_max} < bearing_min {self.bearing_min}')

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """``(N,)`` bool: which world-frame positions ``xy (N, 2)`` lie inside the sector."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        dx, dy = xy[:, 0] - self.origin[0], xy[:, 1] - self.origin[1]
        r = np.hypot(dx, dy)
        inside = (r >= self.range_min) & (r <= self.range_max)
        if self.bearing_max - self.bearing_min < 2.0 * math.pi:
            # Bearing relative to bearing_min, wrapped to [0, 2 pi).
            rel = np.mod(np.arctan2(dy, dx) - self.yaw - self.bearing_min, 2.0 * math.pi)
            inside &= rel <= self.bearing_max - self.bearing_min
        return inside

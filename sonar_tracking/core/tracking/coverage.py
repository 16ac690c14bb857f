"""The area a scan covered: a polar window of the sensor in the world frame (not in the paper).

A scanning or forward-looking sonar sees the ring sector ``range_min <= r <= range_max``,
``bearing_min <= b <= bearing_max`` around its position, bearings measured counter-clockwise
from the sensor's heading (REP-103). The tracker ends a track whose estimate stays outside the
windows of successive scans for ``track.outside_time`` (it can no longer be observed, so its
existence would only decay slowly on missed detections that are not misses).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.tracking.errors import TrackingInputError

__all__ = ['Coverage']


@dataclass(frozen=True)
class Coverage:
    """Polar window: sensor position ``(x, y)`` [m] and ``heading`` [rad] in the world frame,
    ranges [m] and bearings [rad, relative to the heading, counter-clockwise]. A bearing span of
    ``2 pi`` or more is the full circle."""

    x: float
    y: float
    heading: float
    range_min: float
    range_max: float
    bearing_min: float = -math.pi
    bearing_max: float = math.pi

    def __post_init__(self) -> None:
        values = (self.x, self.y, self.heading, self.range_min, self.range_max, self.bearing_min, self.bearing_max)
        if not all(math.isfinite(v) for v in values):
            raise TrackingInputError(f'coverage {values} has a value that is not finite')
        if not 0.0 <= self.range_min < self.range_max:
            raise TrackingInputError(f'coverage ranges [{self.range_min}, {self.range_max}] must satisfy '
                                     '0 <= range_min < range_max')
        if not self.bearing_min < self.bearing_max:
            raise TrackingInputError(f'coverage bearings [{self.bearing_min}, {self.bearing_max}] must satisfy '
                                     'bearing_min < bearing_max')

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """``(T,)`` bool: the points ``xy (2, T)`` lie inside the window (edges included)."""
        dx, dy = xy[0] - self.x, xy[1] - self.y
        r = np.hypot(dx, dy)
        inside = (r >= self.range_min) & (r <= self.range_max)
        span = self.bearing_max - self.bearing_min
        if span < 2.0 * math.pi:
            rel = np.mod(np.arctan2(dy, dx) - self.heading - self.bearing_min, 2.0 * math.pi)
            inside &= rel <= span
        return inside

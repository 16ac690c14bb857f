"""Planar sensor poses over time, for placing a sector taken at a given stamp.

Odometry arrives at its own rate; :class:`PoseBuffer` keeps the recent poses and interpolates
position linearly and yaw along the shorter arc. Outside the buffered span the nearest pose is
used if it is within ``max_extrapolation`` seconds, otherwise there is no pose (the caller falls
back to its static pose and says so).
"""
from __future__ import annotations

import bisect
import math

__all__ = ['PoseBuffer']

Pose = tuple[float, float, float]


class PoseBuffer:
    """Time-ordered ``(t, x, y, yaw)``; ``pose_at(t)`` interpolates."""

    def __init__(self, max_age: float = 30.0, max_extrapolation: float = 2.0) -> None:
        self.max_age = max_age
        self.max_extrapolation = max_extrapolation
        self._t: list[float] = []
        self._p: list[Pose] = []

    def __len__(self) -> int:
        return len(self._t)

    def clear(self) -> None:
        self._t.clear()
        self._p.clear()

    def add(self, t: float, x: float, y: float, yaw: float) -> None:
        """Insert a pose (out-of-order stamps are placed in order; a repeated stamp replaces)."""
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            self._p[i] = (x, y, yaw)
        else:
            self._t.insert(i, t)
            self._p.insert(i, (x, y, yaw))
        cut = bisect.bisect_left(self._t, self._t[-1] - self.max_age)
        if cut:
            del self._t[:cut], self._p[:cut]

    def pose_at(self, t: float) -> Pose | None:
        """Interpolated pose at ``t``, or None when no pose is near enough."""
        if not self._t:
            return None
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            return self._p[i]
        if i == 0 or i == len(self._t):
            j = 0 if i == 0 else len(self._t) - 1
            return self._p[j] if abs(self._t[j] - t) <= self.max_extrapolation else None
        t0, t1 = self._t[i - 1], self._t[i]
        (x0, y0, a0), (x1, y1, a1) = self._p[i - 1], self._p[i]
        w = (t - t0) / (t1 - t0)
        da = math.remainder(a1 - a0, 2 * math.pi)
        return (x0 + w * (x1 - x0), y0 + w * (y1 - y0), math.remainder(a0 + w * da, 2 * math.pi))

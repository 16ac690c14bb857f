"""Spatial clutter measurement density estimation (SCMDE; Song and Musicki, ESC paper ref. [6]).

Each measurement's clutter density is estimated from the area ``V_n`` of the smallest disc
around it that holds its ``n`` nearest other measurements:

    rho_i = (n - 1) / V_n(i)

For a homogeneous Poisson process of density ``rho``, ``rho * V_n`` is Gamma(n, 1) distributed
(the other points of a Poisson process seen from one of its points are still Poisson), so
``E[1 / V_n] = rho / (n - 1)``: the estimate is unbiased, with relative standard deviation
``1 / sqrt(n - 2)``. (``n / V_n`` would overestimate by ``n / (n - 1)``.)

Edge correction: near the border of the surveillance window part of the disc lies where no
measurement can be, which would make ``V_n`` too large. ``V_n`` is therefore the area of the
disc *inside* the window, measured with a fixed sunflower pattern of points on the disc tested
against the window (a polar sector in the sensor frame). With fewer than ``n + 1`` measurements
in the window, every measurement gets the count estimate ``M / A`` (unbiased for Poisson counts),
``A`` the window area; without a window the order drops to what is available.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

__all__ = ['PolarWindow', 'scmde', 'sunflower']


@dataclass(frozen=True)
class PolarWindow:
    """The surveillance window of a sector, in the sensor frame: ranges and bearings [m, rad]."""

    r_min: float
    r_max: float
    b_min: float
    b_max: float

    @property
    def area(self) -> float:
        return 0.5 * (self.b_max - self.b_min) * (self.r_max ** 2 - self.r_min ** 2)

    def clearance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """A lower bound of each point's distance to the window border (0 outside or undecided)."""
        if self.b_max - self.b_min >= math.pi:
            return np.zeros(np.shape(x))
        r = np.hypot(x, y)
        off = np.arctan2(y, x) - self.b_min
        off = np.remainder(off + math.pi, 2 * math.pi) - math.pi
        span = self.b_max - self.b_min
        to_sides = r * np.minimum(np.sin(np.clip(off, 0.0, math.pi / 2)), np.sin(np.clip(span - off, 0.0, math.pi / 2)))
        return np.clip(np.minimum(np.minimum(r - self.r_min, self.r_max - r), to_sides), 0.0, None)

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether sensor-frame points lie in the window."""
        r = np.hypot(x, y)
        b = np.arctan2(y, x)
        mid = 0.5 * (self.b_min + self.b_max)
        off = np.remainder(b - mid + math.pi, 2 * math.pi) - math.pi
        return (r >= self.r_min) & (r <= self.r_max) & (np.abs(off) <= 0.5 * (self.b_max - self.b_min))


def sunflower(n: int) -> np.ndarray:
    """``n`` points spread evenly over the unit disc (Vogel's sunflower spiral), shape (n, 2)."""
    k = np.arange(n) + 0.5
    rad = np.sqrt(k / n)
    ang = k * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([rad * np.cos(ang), rad * np.sin(ang)], axis=1)


_DISC = sunflower(64)


def scmde(points: np.ndarray, order: int = 6, window: PolarWindow | None = None) -> np.ndarray:
    """Clutter density [1/m^2] at each of ``points`` ``(N, 2)`` (sensor-frame metres).

    ``window`` enables the edge correction and the count fallback; without it, sparse scans
    (fewer than three points) get 0.
    """
    pts = np.asarray(points, dtype=float)
    m = len(pts)
    if m == 0:
        return np.zeros(0)
    if window is not None and m < order + 1:
        return np.full(m, m / window.area)
    n = min(order, m - 1)
    if n < 2:
        return np.zeros(m)
    dist, _ = cKDTree(pts).query(pts, k=n + 1)
    radius = dist[:, n]
    area = math.pi * radius ** 2
    if window is not None:
        # Only discs that may cross the border need the sunflower test.
        near = np.nonzero(radius > window.clearance(pts[:, 0], pts[:, 1]))[0]
        if len(near):
            sx = pts[near, 0:1] + radius[near, None] * _DISC[None, :, 0]
            sy = pts[near, 1:2] + radius[near, None] * _DISC[None, :, 1]
            inside = window.contains(sx, sy).mean(axis=1)
            area[near] *= np.maximum(inside, 1.0 / len(_DISC))
    # Coincident points would give a zero area; a floor keeps the estimate finite.
    return (n - 1) / np.maximum(area, 1e-12)

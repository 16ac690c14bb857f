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

Clutter uniform over cells (:func:`scmde_cells`): a CFAR detector holds a false-alarm rate per
range-bearing cell of the polar image, and a cell's area grows with its range, so its false
detections are uniform over range and bearing, not over the sea's area: their density per m^2 at
range ``r`` is a density in ``(r, theta)`` over ``r``. :func:`scmde_cells` estimates each
measurement's density in ``(r, r_ref theta)`` (a rectangle, ``r_ref`` the window's middle range,
so that neighbourhoods there are as in metres) with the same estimator and then divides by
``r / r_ref``. On an imaging sonar's fan (0.3-30 m) the area estimate puts the clutter within 2 m
of the head 4 to 30 times too low.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.jit import kernel

__all__ = ['PolarWindow', 'RectWindow', 'scmde', 'scmde_cells', 'cell_count_density', 'per_area', 'sunflower']


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

    def _bearing_test(self) -> tuple[float, float, float]:
        """``cos``, ``sin`` of the middle bearing and ``cos`` of half the span (-2 for a full circle)."""
        mid, half = 0.5 * (self.b_min + self.b_max), 0.5 * (self.b_max - self.b_min)
        return math.cos(mid), math.sin(mid), (math.cos(half) if half < math.pi else -2.0)

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether sensor-frame points lie in the window."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        out = np.empty(x.shape, dtype=bool)
        _contains_into(np.ascontiguousarray(x).reshape(-1), np.ascontiguousarray(y).reshape(-1),
                       self.r_min, self.r_max, *self._bearing_test(), out.reshape(-1))
        return out

    def disc_fraction(self, x: np.ndarray, y: np.ndarray, radius: np.ndarray, disc: np.ndarray | None = None
                      ) -> np.ndarray:
        """The fraction of each disc of ``radius`` centred on sensor-frame ``(x, y)`` (1-D arrays)
        inside the window: of the points ``disc (P, 2)`` on the unit disc (default :data:`DISC`),
        scaled and moved onto it, the share :meth:`contains` holds."""
        x, y, radius = (np.ascontiguousarray(v, dtype=float) for v in (x, y, radius))
        out = np.empty(x.shape)
        _disc_fraction_into(x, y, radius, DISC if disc is None else np.ascontiguousarray(disc, dtype=float),
                            self.r_min, self.r_max, *self._bearing_test(), out)
        return out


@dataclass(frozen=True)
class RectWindow:
    """An axis-aligned rectangle ``[x_min, x_max] x [y_min, y_max]``: the window of
    :func:`scmde_cells`, with :class:`PolarWindow`'s interface."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    @property
    def area(self) -> float:
        return (self.x_max - self.x_min) * (self.y_max - self.y_min)

    def clearance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Each point's distance to the rectangle's border (0 outside)."""
        d = np.minimum(np.minimum(np.asarray(x) - self.x_min, self.x_max - np.asarray(x)),
                       np.minimum(np.asarray(y) - self.y_min, self.y_max - np.asarray(y)))
        return np.clip(d, 0.0, None)

    def disc_fraction(self, x: np.ndarray, y: np.ndarray, radius: np.ndarray, disc: np.ndarray | None = None
                      ) -> np.ndarray:
        """As :meth:`PolarWindow.disc_fraction`, for the rectangle."""
        d = DISC if disc is None else np.asarray(disc, dtype=float)
        px = np.asarray(x, dtype=float)[:, None] + np.asarray(radius, dtype=float)[:, None] * d[None, :, 0]
        py = np.asarray(y, dtype=float)[:, None] + np.asarray(radius, dtype=float)[:, None] * d[None, :, 1]
        inside = (px >= self.x_min) & (px <= self.x_max) & (py >= self.y_min) & (py <= self.y_max)
        return inside.mean(axis=1)


@kernel
def _inside(x, y, r_min, r_max, cos_mid, sin_mid, cos_half):
    """Whether the point ``(x, y)`` lies in the polar window (compiled scalar): its range within
    ``[r_min, r_max]`` and its bearing within half the span of the middle bearing, i.e. the cosine
    of the angle to the middle direction ``(cos_mid, sin_mid)`` at least ``cos_half``."""
    r = np.sqrt(x * x + y * y)
    return r >= r_min and r <= r_max and x * cos_mid + y * sin_mid >= r * cos_half


@kernel
def _contains_into(x, y, r_min, r_max, cos_mid, sin_mid, cos_half, out):
    """:func:`_inside` of every point (1-D arrays) into ``out``."""
    for i in range(x.size):
        out[i] = _inside(x[i], y[i], r_min, r_max, cos_mid, sin_mid, cos_half)


@kernel
def _disc_fraction_into(x, y, radius, disc, r_min, r_max, cos_mid, sin_mid, cos_half, out):
    """Per disc, the share of the unit-disc points ``disc (P, 2)``, scaled by its radius about its
    centre, that :func:`_inside` holds, into ``out``."""
    for i in range(x.size):
        n = 0
        for j in range(disc.shape[0]):
            n += _inside(x[i] + radius[i] * disc[j, 0], y[i] + radius[i] * disc[j, 1], r_min, r_max,
                         cos_mid, sin_mid, cos_half)
        out[i] = n / disc.shape[0]


def sunflower(n: int) -> np.ndarray:
    """``n`` points spread evenly over the unit disc (Vogel's sunflower spiral), shape (n, 2)."""
    k = np.arange(n) + 0.5
    rad = np.sqrt(k / n)
    ang = k * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([rad * np.cos(ang), rad * np.sin(ang)], axis=1)


#: The points of the edge correction's disc test.
DISC = sunflower(64)


@kernel
def _nth_neighbour(pts, n, out):
    """Distance from each point of ``pts (M, 2)`` to its ``n``-th nearest other point (``n < M``),
    into ``out``: the same numbers as ``cKDTree(pts).query(pts, n + 1)[0][:, n]``, found on a grid of
    about three points per cell, searched in growing square rings until no farther cell can hold a
    nearer point (compiled)."""
    m = pts.shape[0]
    x0, x1, y0, y1 = pts[0, 0], pts[0, 0], pts[0, 1], pts[0, 1]
    for i in range(m):
        x0, x1 = min(x0, pts[i, 0]), max(x1, pts[i, 0])
        y0, y1 = min(y0, pts[i, 1]), max(y1, pts[i, 1])
    sx, sy = x1 - x0, y1 - y0
    cell = np.sqrt(3.0 * sx * sy / m)
    if not cell > 0.0:                        # points on a line, or all in one place
        cell = max(max(sx, sy) / m, 1e-9)
    nx, ny = int(sx / cell) + 1, int(sy / cell) + 1
    while nx * ny > 4 * m + 4:                # a long thin spread: fewer, larger cells
        cell *= 1.5
        nx, ny = int(sx / cell) + 1, int(sy / cell) + 1
    # Points by cell (counting sort).
    cell_of = np.empty(m, np.int64)
    start = np.zeros(nx * ny + 1, np.int64)
    for i in range(m):
        c = min(int((pts[i, 0] - x0) / cell), nx - 1) * ny + min(int((pts[i, 1] - y0) / cell), ny - 1)
        cell_of[i] = c
        start[c + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    items = np.empty(m, np.int64)
    for i in range(m):
        items[fill[cell_of[i]]] = i
        fill[cell_of[i]] += 1
    margin = 1e-9 * (sx + sy + cell)
    best = np.empty(n + 1)
    for i in range(m):
        px, py = pts[i, 0], pts[i, 1]
        cx, cy = cell_of[i] // ny, cell_of[i] % ny
        best[:] = np.inf
        r = 0
        while True:
            for gx in range(max(cx - r, 0), min(cx + r, nx - 1) + 1):
                for gy in range(max(cy - r, 0), min(cy + r, ny - 1) + 1):
                    if abs(gx - cx) != r and abs(gy - cy) != r:
                        continue                     # searched in an earlier ring
                    c = gx * ny + gy
                    for a in range(start[c], start[c + 1]):
                        j = items[a]
                        dx, dy = px - pts[j, 0], py - pts[j, 1]
                        d2 = dx * dx + dy * dy
                        if d2 < best[n]:
                            k = n
                            while k > 0 and best[k - 1] > d2:
                                best[k] = best[k - 1]
                                k -= 1
                            best[k] = d2
            # Every cell not yet searched lies beyond the square's nearest side (less a rounding margin).
            gap = np.inf
            if cx - r > 0:
                gap = min(gap, px - x0 - (cx - r) * cell)
            if cx + r < nx - 1:
                gap = min(gap, x0 + (cx + r + 1) * cell - px)
            if cy - r > 0:
                gap = min(gap, py - y0 - (cy - r) * cell)
            if cy + r < ny - 1:
                gap = min(gap, y0 + (cy + r + 1) * cell - py)
            if gap == np.inf or best[n] <= (gap - margin) ** 2 and gap > margin:
                break
            r += 1
        out[i] = np.sqrt(best[n])


def scmde(points: np.ndarray, order: int = 6, window: PolarWindow | RectWindow | None = None) -> np.ndarray:
    """Clutter density [1/m^2] at each of ``points`` ``(N, 2)`` (sensor-frame metres).

    ``window`` enables the edge correction and the count fallback; without it, sparse scans
    (fewer than three points) get 0. Points that are not finite, or whose spread overflows, raise
    ValueError.
    """
    pts = np.asarray(points, dtype=float)
    m = len(pts)
    if m == 0:
        return np.zeros(0)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f'points must have shape (N, 2), got {pts.shape}')
    with np.errstate(over='ignore', invalid='ignore'):
        spread = np.ptp(pts, axis=0)
    if not np.isfinite(spread).all():    # also every point finite
        raise ValueError('points must be finite, and their spread too')
    if window is not None and m < order + 1:
        return np.full(m, m / window.area)
    n = min(order, m - 1)
    if n < 2:
        return np.zeros(m)
    radius = np.empty(m)
    _nth_neighbour(np.ascontiguousarray(pts), n, radius)
    area = math.pi * radius ** 2
    if window is not None:
        # Only discs that may cross the border need the sunflower test.
        near = np.nonzero(radius > window.clearance(pts[:, 0], pts[:, 1]))[0]
        if len(near):
            inside = window.disc_fraction(pts[near, 0], pts[near, 1], radius[near])
            area[near] *= np.maximum(inside, 1.0 / len(DISC))
    # Coincident points would give a zero area; a floor keeps the estimate finite.
    return (n - 1) / np.maximum(area, 1e-12)


def scmde_cells(r: np.ndarray, b: np.ndarray, order: int, window: PolarWindow, r_floor: float,
                edge_correction: bool = True) -> np.ndarray:
    """Clutter density [1/m^2] at each measurement at ranges ``r`` and bearings ``b`` (sensor frame,
    1-D) for clutter uniform over the polar image's cells (module docstring): :func:`scmde` in
    ``(r, r_ref b)``, over the window's rectangle there when ``edge_correction``, converted by
    :func:`per_area` (``r_floor > 0``: the nearest range a cell's centre can have)."""
    r = np.asarray(r, dtype=float)
    b = np.asarray(b, dtype=float)
    if r.shape != b.shape or r.ndim != 1:
        raise ValueError(f'ranges and bearings must be 1-D arrays of one length, got {r.shape} and {b.shape}')
    r_ref = max(0.5 * (window.r_min + window.r_max), r_floor)
    mid = 0.5 * (window.b_min + window.b_max)
    rect = RectWindow(window.r_min, window.r_max, r_ref * (window.b_min - mid), r_ref * (window.b_max - mid))
    rho = scmde(np.stack([r, r_ref * (b - mid)], axis=-1).reshape(-1, 2), order, rect if edge_correction else None)
    return per_area(rho * r_ref, r, r_floor)


def cell_count_density(count: int, r: np.ndarray, window: PolarWindow, r_floor: float) -> np.ndarray:
    """The count estimate for clutter uniform over cells: ``count`` points over the window's ranges
    and bearings, as densities [1/m^2] at ranges ``r`` (:func:`per_area`)."""
    return per_area(count / ((window.r_max - window.r_min) * (window.b_max - window.b_min)), r, r_floor)


def per_area(rho_rb, r: np.ndarray, r_floor: float) -> np.ndarray:
    """A density over range and bearing [1/(m rad)] as one over area [1/m^2] at ranges ``r``: over
    ``max(r, r_floor)``, the area element being ``r dr dtheta``."""
    if not r_floor > 0:
        raise ValueError(f'r_floor must be > 0, not {r_floor}')
    return rho_rb / np.maximum(np.asarray(r, dtype=float), r_floor)

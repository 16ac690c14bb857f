"""The simulated world: targets, the sonar platform, and where clutter is heavy.

Clutter strength is the rate ``lam`` of the exponential amplitude law (ESC eq. 15): a region
with a small ``lam`` has a heavy tail and gives many false alarms at a given threshold. The
background ``lam`` applies everywhere except inside the polygons of :class:`ClutterRegion`
(ESC paper Figure 15: lam 1.6 in the white region, 0.8 in the yellow one).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from sonar_tracking.sim.motion import StaticTrajectory, Trajectory
from sonar_tracking.sim.shapes import Shape, shape

if TYPE_CHECKING:
    from sonar_tracking.sim.structure import Structure

__all__ = ['Target', 'ClutterRegion', 'Scene', 'points_in_polygon']


@dataclass
class Target:
    """A simulated target: id, motion, echo shape and signal-to-noise ratio [dB]."""

    target_id: int
    trajectory: Trajectory
    shape: Shape = field(default_factory=lambda: shape('point'))
    snr_db: float = 8.0


def points_in_polygon(xy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Boolean mask of points ``(..., 2)`` inside a simple polygon ``(N, 2)`` (even-odd rule)."""
    x, y = xy[..., 0], xy[..., 1]
    inside = np.zeros(x.shape, dtype=bool)
    px, py = polygon[:, 0], polygon[:, 1]
    for i in range(len(polygon)):
        x1, y1, x2, y2 = px[i - 1], py[i - 1], px[i], py[i]
        crosses = (y1 > y) != (y2 > y)
        with np.errstate(divide='ignore', invalid='ignore'):
            x_cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (x < x_cross)
    return inside


@dataclass(frozen=True, eq=False)
class ClutterRegion:
    """A polygon (world frame, metres) where the clutter rate is ``lam``."""

    lam: float
    polygon: np.ndarray

    def __post_init__(self) -> None:
        if not (self.lam > 0 and math.isfinite(self.lam)):
            raise ValueError(f'clutter rate lam = {self.lam} must be > 0')
        object.__setattr__(self, 'polygon', np.asarray(self.polygon, dtype=float))


@dataclass
class Scene:
    """Targets, sonar platform motion, clutter map and static structure (None: open water);
    ``duration`` is the scenario length [s]."""

    targets: list[Target]
    platform: Trajectory = field(default_factory=lambda: StaticTrajectory(0.0, 0.0))
    lam: float = 1.0
    regions: list[ClutterRegion] = field(default_factory=list)
    duration: float = math.inf
    depth: float = 1.5
    structure: Structure | None = None

    def lam_at(self, xy: np.ndarray) -> np.ndarray | float:
        """Clutter rate at world points ``(..., 2)``; a scalar when the map is homogeneous."""
        if not self.regions:
            return self.lam
        lam = np.full(xy.shape[:-1], self.lam, dtype=float)
        for region in self.regions:  # later regions win where they overlap
            lam[points_in_polygon(xy, region.polygon)] = region.lam
        return lam

    def platform_pose(self, t: float) -> tuple[float, float, float, float, float]:
        """Sonar pose at ``t``: ``(x, y, yaw, vx, vy)`` in the world frame."""
        s = self.platform.state(t)
        return float(s[0]), float(s[1]), float(self.platform.heading(t)), float(s[2]), float(s[3])

    def truth(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Target ids ``(N,)`` and world states ``(N, 4) = [x, y, vx, vy]`` at ``t``."""
        ids = np.array([tg.target_id for tg in self.targets], dtype=np.uint32)
        states = np.array([tg.trajectory.state(t) for tg in self.targets], dtype=float).reshape(-1, 4)
        return ids, states

"""What a simulated sensor produces: one sector at a time."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.sector import SectorGeometry

__all__ = ['SimSector', 'Pose']

#: Sensor pose in the world frame: ``(x, y, yaw)`` [m, m, rad].
Pose = tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class SimSector:
    """One sector: linear echo amplitudes ``(n_bins, n_beams)`` float32 and where they were taken.

    ``stamp`` is the time [s] of the ping of column 0; ``pose`` the sensor pose then;
    ``end_of_sweep`` marks the last sector of a sweep (360 deg turn, sector-mode pass, or a
    whole harbour scan).
    """

    stamp: float
    amplitudes: np.ndarray
    geometry: SectorGeometry
    pose: Pose
    end_of_sweep: bool

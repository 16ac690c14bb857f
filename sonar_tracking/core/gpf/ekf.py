"""The EKF baseline (FLS paper Figure 13): an extended Kalman filter per target on the segmented regions.

Where the GPF and the SIR filter weigh the image at every particle, the EKF sees only what the
segmentation found: each region of ``/fls/regions`` as a range and bearing from the sonar,
``z = [r, b]``, ``h(x) = [sqrt(dx^2 + dy^2), atan2(dy, dx) - yaw]`` with ``(dx, dy)`` the target's
offset from the sonar, linearised at the prediction (the extended Kalman filter), with noise
``R = diag(sigma_range^2, sigma_bearing^2)`` (the filter: :class:`.filters.Ekf`). The motion
model, its process noise and the Kalman prediction are the shared ones (:mod:`~..tracking.motion`,
:mod:`~..tracking.noise`, :func:`~..tracking.kalman.predict`); the gate is the chi-square gate of
:func:`~..tracking.gating.gate_threshold`. Tracks and regions are paired by global nearest
neighbour (least total squared Mahalanobis distance within the gate,
:func:`.management.gated_assignment`). The tracker is the GPF's frame tracker
(:class:`.tracker.GpfTracker`) with this filter: births, confirmation, widening while lost and
ending are the same code and settings, so the methods differ only in how they use a frame. A
region is the EKF's measurement, so there is no re-finding; there is no image, so no templates and
no coverage test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, setting
from sonar_tracking.core.gpf.config import GpfConfig
from sonar_tracking.core.gpf.filters import Ekf, polar_measurement
from sonar_tracking.core.gpf.tracker import GpfTracker
from sonar_tracking.core.tracking.gating import gate_threshold

__all__ = ['EkfConfig', 'EkfTracker', 'polar_measurement']


@dataclass(frozen=True)
class EkfConfig(Config):
    """Measurement model of the EKF baseline (ours: the region centroids' scatter about the imaged
    target centres on simulated SeaKing 675 kHz frames)."""

    sigma_range: float = setting(0.15, 'range std of a region centroid', unit='m', low=0.0, high=1e3, low_open=True)
    sigma_bearing_deg: float = setting(1.0, 'bearing std of a region centroid', unit='deg', low=0.0, high=90.0,
                                       low_open=True)
    gate_probability: float = setting(0.99, 'P_G of the chi-square gate on the innovation', low=0.5, high=0.999999)


class EkfTracker(GpfTracker):
    """Multi-target EKF on regions; ``step`` has the GPF tracker's signature without the image."""

    def __init__(self, config: GpfConfig | None = None, ekf: EkfConfig | None = None) -> None:
        self.ekf = ekf or EkfConfig()
        R = np.diag([self.ekf.sigma_range ** 2, math.radians(self.ekf.sigma_bearing_deg) ** 2])
        super().__init__(config, track_filter=Ekf(R, gate_threshold(self.ekf.gate_probability, 2)))

    def step(self, stamp: float, regions: np.ndarray | None,  # type: ignore[override]
             sensor_pose: tuple[float, float, float] | None = None) -> np.ndarray:
        """Process the regions of the frame at ``stamp`` seen from ``sensor_pose`` (image frame;
        the origin looking along x if None); returns GPF_TRACK_DTYPE records."""
        return self._frame(stamp, None, None, regions, sensor_pose)

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
:func:`.management.gated_assignment`). Births, confirmation,
widening while lost and termination follow the GPF tracker's settings (:mod:`.management`), so the
methods differ only in how they use a frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import Config, setting
from ..tracking.gating import gate_threshold
from .config import GpfConfig
from .filters import Ekf, polar_measurement, wrap_angle
from .management import birth_covariance, gated_assignment, should_end, unexplained, widen
from .track import GpfTrack, tracks_to_records
from .tracker import GpfInputError, StepReport, regions_xy

__all__ = ['EkfConfig', 'EkfTracker', 'polar_measurement']


@dataclass(frozen=True)
class EkfConfig(Config):
    """Measurement model of the EKF baseline (ours: the region centroids' scatter about the imaged
    target centres on simulated SeaKing 675 kHz frames)."""

    sigma_range: float = setting(0.15, 'range std of a region centroid', unit='m', low=0.0, high=1e3, low_open=True)
    sigma_bearing_deg: float = setting(1.0, 'bearing std of a region centroid', unit='deg', low=0.0, high=90.0,
                                       low_open=True)
    gate_probability: float = setting(0.99, 'P_G of the chi-square gate on the innovation', low=0.5, high=0.999999)


class EkfTracker:
    """Multi-target EKF on regions; ``step`` has the GPF tracker's signature without the image."""

    method = 'ekf'

    def __init__(self, config: GpfConfig | None = None, ekf: EkfConfig | None = None) -> None:
        self.config = config or GpfConfig()
        self.ekf = ekf or EkfConfig()
        self.gamma = gate_threshold(self.ekf.gate_probability, 2)
        self.R = np.diag([self.ekf.sigma_range ** 2, math.radians(self.ekf.sigma_bearing_deg) ** 2])
        self.filter = Ekf(self.R)
        self.tracks: list[GpfTrack] = []
        self.next_id = 1
        self.stamp: float | None = None
        self.report = StepReport()

    def step(self, stamp: float, regions: np.ndarray | None, sensor_pose: tuple[float, float, float] | None = None
             ) -> np.ndarray:
        """Process the regions of the frame at ``stamp`` seen from ``sensor_pose`` (image frame;
        the origin looking along x if None); returns GPF_TRACK_DTYPE records."""
        if not math.isfinite(stamp):
            raise GpfInputError(f'frame stamp {stamp} is not finite')
        sensor = tuple(float(v) for v in (sensor_pose or (0.0, 0.0, 0.0)))
        xy, bad = regions_xy(regions)
        rep = StepReport(stamp=float(stamp), regions=len(xy), bad_regions=bad)
        if self.stamp is not None and stamp < self.stamp:
            rep.reset = f'time went back from {self.stamp:.3f} s to {stamp:.3f} s'
            self.tracks, self.stamp = [], None
        dt = 0.0 if self.stamp is None else float(stamp - self.stamp)
        self.stamp = float(stamp)
        self.filter.predict(self.tracks, dt, self.config.motion.noise, 0, None)
        z = np.column_stack([np.hypot(xy[:, 0] - sensor[0], xy[:, 1] - sensor[1]),
                             wrap_angle(np.arctan2(xy[:, 1] - sensor[1], xy[:, 0] - sensor[0]) - sensor[2])])
        used = self._update(z, sensor)
        for tr in self.tracks:
            tr.stamp = float(stamp)
            rep.seen += tr.seen
            rep.missed += not tr.seen
        keep = [tr for tr in self.tracks if not should_end(tr.confirmed, tr.last_seen, tr.stamp, self.config.lost)]
        rep.ended = len(self.tracks) - len(keep)
        self.tracks = keep
        rep.born = self._births(xy, used, sensor)
        for tr in self.tracks:
            tr.confirmed = tr.confirmed or tr.hits >= self.config.birth.confirm_hits
        rep.tracks, rep.confirmed = len(self.tracks), sum(tr.confirmed for tr in self.tracks)
        self.report = rep
        return tracks_to_records(self.tracks)

    def _update(self, z: np.ndarray, sensor: tuple[float, float, float]) -> np.ndarray:
        """Global-nearest-neighbour pairing and the EKF update; returns which regions were used."""
        n, t = len(z), len(self.tracks)
        used = np.zeros(n, bool)
        if t == 0:
            return used
        cost = np.full((t, max(n, 1)), np.inf)
        parts = []
        for i, tr in enumerate(self.tracks):
            H, S_inv, nu = self.filter.innovations(tr, z, sensor)
            if n:
                cost[i, :n] = np.einsum('na,ab,nb->n', nu, S_inv, nu)
            parts.append((H, S_inv, nu))
        pairs = dict(gated_assignment(cost[:, :n], self.gamma)) if n else {}
        for i, tr in enumerate(self.tracks):
            k = pairs.get(i)
            if k is None:
                tr.seen = False
                tr.misses += 1
                tr.cov = widen(tr.cov, self.config.lost)
                continue
            H, _, nu = parts[i]
            self.filter.update(tr, nu[k], H)
            tr.seen, tr.misses = True, 0
            tr.hits += 1
            tr.last_seen = self.stamp
            used[k] = True
        return used

    def _births(self, xy: np.ndarray, used: np.ndarray, sensor: tuple[float, float, float]) -> int:
        c = self.config.birth
        if len(xy) == 0:
            return 0
        covs = birth_covariance(xy, c, sensor[:2])
        means = np.array([tr.mean[:2] for tr in self.tracks]).reshape(-1, 2)
        pcov = np.array([tr.cov[:2, :2] for tr in self.tracks]).reshape(-1, 2, 2)
        free = unexplained(xy, means, pcov, c, covs, c.separation) & ~used
        idx = np.flatnonzero(free)[:max(0, c.max_tracks - len(self.tracks))]
        for i in idx:
            self.tracks.append(GpfTrack(track_id=self.next_id, mean=np.array([xy[i, 0], xy[i, 1], 0.0, 0.0]),
                                        cov=covs[i], template=np.zeros(0), born=self.stamp, stamp=self.stamp,
                                        last_seen=self.stamp, confirmed=c.confirm_hits <= 1))
            self.next_id += 1
        return int(idx.size)

"""The filters of the FLS trackers behind one interface: how a track's state moves, weighs a frame,
widens when the target is not seen, and starts again from a Gaussian.

The frame tracker (:class:`~.tracker.GpfTracker`) wires births, re-finding, templates, ending and
confirmation once and asks its filter only for these steps, so the methods differ only in the
filter:

* :class:`GaussianPF`, the paper's Gaussian particle filter (§4.1): the track is a Gaussian; each
  frame draws K particles from the prediction (eqs. 5-6), weighs them (eq. 7) and takes the
  posterior moments (eq. 8), prediction by sampling the motion model (eqs. 9-12). The likelihood
  sees only positions, so the posterior velocity is the prediction's conditional given the
  posterior position (eq. 8 without its Monte Carlo error).
* :class:`SirPF`, the SIR baseline of Figure 13 (:mod:`.sir`): the track keeps its weighted
  particles between frames, resampled and roughened after each update.
* :class:`Ekf`, the EKF baseline of Figure 13 (:mod:`.ekf`): the Gaussian predicted by the Kalman
  equations and updated on a region's range and bearing; it does not weigh the image.

Every method draws its random numbers from the generator it is given, in a fixed order, so a run is
a function of its seed.
"""
from __future__ import annotations

import math

import numpy as np

from sonar_tracking.core.gpf import sir
from sonar_tracking.core.gpf.fusion import normalise_log
from sonar_tracking.core.gpf.gaussian import (
    condition_velocity,
    floor_position,
    kalman_update,
    motion_matrices,
    predict,
    sample_gaussian,
    weighted_moments,
)
from sonar_tracking.core.gpf.management import gated_assignment
from sonar_tracking.core.gpf.track import GpfTrack
from sonar_tracking.core.tracking.kalman import predict as kalman_predict

__all__ = ['TrackFilter', 'GaussianPF', 'SirPF', 'Ekf', 'FILTERS', 'polar_measurement', 'wrap_angle']


class TrackFilter:
    """The interface (the default methods are those of a filter whose state is the Gaussian alone).

    ``rng`` is the tracker's generator; it is None only for a filter that does not weigh the image
    (the EKF draws nothing).
    """

    #: Name of the method (``GpfTracker(method=...)``).
    name = ''
    #: Whether the filter weighs the image (particle filters) or only regions (the EKF).
    weighs_image = True

    def predict(self, tracks: list[GpfTrack], dt: float, q: float, k: int, rng: np.random.Generator | None) -> None:
        """Move every track ``dt`` seconds on (``q`` the motion model's noise, ``k`` particles)."""
        raise NotImplementedError

    def particles(self, tracks: list[GpfTrack], k: int, rng: np.random.Generator | None) -> list[np.ndarray]:
        """The ``(K, 4)`` particles each track weighs on this frame."""
        raise NotImplementedError

    def posterior(self, tr: GpfTrack, particles: np.ndarray, log_likelihood: np.ndarray, floor: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Normalised weights, posterior mean and covariance (position variance floored at ``floor``)."""
        raise NotImplementedError

    def accepted(self, tr: GpfTrack, particles: np.ndarray, weights: np.ndarray, floor: float,
                 rng: np.random.Generator | None) -> None:
        """The track took the posterior of this frame."""

    def missed(self, tr: GpfTrack, inflation: float) -> None:
        """The frame did not see the target; ``tr.cov`` is already widened (step 3)."""

    def restart(self, tr: GpfTrack, k: int, rng: np.random.Generator | None) -> None:
        """The track (born, or re-found on a region) starts again from its Gaussian."""

    def update_on_regions(self, tracks: list[GpfTrack], xy: np.ndarray, sensor: tuple[float, float, float]
                          ) -> dict[int, int]:
        """Only for a filter that does not weigh the image: pair the tracks with the regions
        ``xy (N, 2)`` seen from ``sensor`` and update the paired ones; ``{track index: region index}``."""
        raise NotImplementedError


class GaussianPF(TrackFilter):
    """The Gaussian particle filter (module docstring)."""

    name = 'gpf'

    def predict(self, tracks, dt, q, k, rng):
        if dt <= 0.0:
            return
        for tr in tracks:
            tr.mean, tr.cov = predict(tr.mean, tr.cov, dt, q, k, rng)                    # eqs. (9)-(12)

    def particles(self, tracks, k, rng):
        # One draw for all tracks: the numbers each track's sample_gaussian would draw in turn.
        z = rng.standard_normal((len(tracks), k, tracks[0].mean.size))
        return [sample_gaussian(tr.mean, tr.cov, k, z=z[i]) for i, tr in enumerate(tracks)]  # eqs. (5)-(6)

    def posterior(self, tr, particles, log_likelihood, floor):
        w = normalise_log(log_likelihood)                                                     # eq. (7)
        mean, cov = weighted_moments(particles, w)                                            # eq. (8)
        cov = floor_position(cov, floor)
        mean, cov = condition_velocity(tr.mean, tr.cov, mean[:2], cov[:2, :2])
        return w, mean, cov


class SirPF(TrackFilter):
    """The SIR particle filter baseline (module docstring)."""

    name = 'sir'

    def predict(self, tracks, dt, q, k, rng):
        if dt <= 0.0:
            return
        for tr in tracks:
            tr.particles = sir.propagate(tr.particles, dt, q, rng)
            tr.mean, tr.cov = weighted_moments(tr.particles, tr.weights)

    def particles(self, tracks, k, rng):
        return [tr.particles for tr in tracks]

    def posterior(self, tr, particles, log_likelihood, floor):
        w = normalise_log(np.log(tr.weights) + log_likelihood)
        mean, cov = weighted_moments(particles, w)
        return w, mean, floor_position(cov, floor)     # the particles keep their own velocities

    def accepted(self, tr, particles, weights, floor, rng):
        tr.particles, tr.weights = sir.resample(particles, weights, rng)
        tr.particles = sir.roughen(tr.particles, floor, rng)

    def missed(self, tr, inflation):
        tr.particles = sir.spread(tr.particles, tr.weights, inflation, tr.cov)

    def restart(self, tr, k, rng):
        tr.particles = sample_gaussian(tr.mean, tr.cov, k, rng)
        tr.weights = np.full(k, 1.0 / k)


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Angles wrapped to ``[-pi, pi)``."""
    return np.remainder(np.asarray(a) + math.pi, 2 * math.pi) - math.pi


def polar_measurement(x: np.ndarray, sensor: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """``h(x)`` (range, bearing re the sonar heading) and its Jacobian ``(2, 4)`` at state ``x``."""
    dx, dy = x[0] - sensor[0], x[1] - sensor[1]
    r2 = max(dx * dx + dy * dy, 1e-12)
    r = math.sqrt(r2)
    h = np.array([r, math.atan2(dy, dx) - sensor[2]])
    H = np.array([[dx / r, dy / r, 0.0, 0.0], [-dy / r2, dx / r2, 0.0, 0.0]])
    return h, H


class Ekf(TrackFilter):
    """The extended Kalman filter on regions (module docstring): ``R`` the range-bearing noise,
    ``gamma`` the chi-square gate on the innovation."""

    name = 'ekf'
    weighs_image = False

    def __init__(self, R: np.ndarray, gamma: float) -> None:
        self.R = R
        self.gamma = gamma

    def predict(self, tracks, dt, q, k, rng):
        if dt <= 0.0 or not tracks:
            return
        F, Q = motion_matrices(dt, q)
        x = np.stack([tr.mean for tr in tracks], axis=1)[:, None, :]             # (4, 1, T)
        P = np.stack([tr.cov for tr in tracks], axis=2)[:, :, None, :]           # (4, 4, 1, T)
        x, P = kalman_predict(x, P, F[None], Q[None])
        for i, tr in enumerate(tracks):
            tr.mean, tr.cov = x[:, 0, i].copy(), P[:, :, 0, i].copy()

    def innovations(self, tr: GpfTrack, z: np.ndarray, sensor: tuple[float, float, float]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(H, S^-1, nu (N, 2))`` of the track against range-bearing measurements ``z``."""
        h, H = polar_measurement(tr.mean, sensor)
        S_inv = np.linalg.inv(H @ tr.cov @ H.T + self.R)
        nu = z - h[None, :]
        nu[:, 1] = wrap_angle(nu[:, 1])
        return H, S_inv, nu

    def update_on_regions(self, tracks: list[GpfTrack], xy: np.ndarray, sensor: tuple[float, float, float]
                          ) -> dict[int, int]:
        """Pair tracks and regions ``xy (N, 2)`` by global nearest neighbour on the range-bearing
        innovations within the gate (:func:`.management.gated_assignment`) and apply the EKF update
        of each pair; returns ``{track index: region index}``."""
        if not tracks or len(xy) == 0:
            return {}
        d = xy - np.asarray(sensor[:2])[None, :]
        z = np.column_stack([np.hypot(d[:, 0], d[:, 1]), wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - sensor[2])])
        cost = np.empty((len(tracks), len(z)))
        parts = []
        for i, tr in enumerate(tracks):
            H, S_inv, nu = self.innovations(tr, z, sensor)
            cost[i] = np.einsum('na,ab,nb->n', nu, S_inv, nu)
            parts.append((H, nu))
        pairs = dict(gated_assignment(cost, self.gamma))
        for i, k in pairs.items():
            H, nu = parts[i]
            tracks[i].mean, tracks[i].cov = kalman_update(tracks[i].mean, tracks[i].cov, nu[k], H, self.R)
        return pairs


#: The particle filters by method name (``GpfTracker(method=...)``).
FILTERS = {'gpf': GaussianPF, 'sir': SirPF}

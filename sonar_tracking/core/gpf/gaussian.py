"""The Gaussian particle filter of Kotecha and Djuric (FLS paper §4.1, eqs. 5-12).

The filter keeps one Gaussian per track and never resamples:

* **measurement update** (eqs. 6-8): draw K particles from the predicted Gaussian
  ``N(x; x_bar_t, sigma_bar_t)`` (the importance function is the prior), weight each by the
  likelihood ``p(y_t | x_n)``, normalise the weights (step 2 of §4.2.3) and take the weighted mean
  ``mu_t`` and covariance ``sigma_t``: the posterior ``N(x; mu_t, sigma_t)`` (eq. 8);
* **prediction** (eqs. 9-12): draw K particles from the posterior, move each by sampling the
  motion model ``p(x_{t+1} | x_n)``, and take their plain mean (eq. 10) and covariance (eq. 11).

Eq. (11) as printed divides by K (the sample covariance about the sample mean); we keep it. The
motion model is constant velocity (ESC eq. 3, :class:`~..tracking.motion.ConstantVelocity`) with the
continuous white-noise acceleration ``Q`` (:func:`~..tracking.noise.white_noise_acceleration`),
the same pieces as the IMM-IPDA tracker's.

A weighted covariance from few effective particles can be nearly singular; sampling uses a
Cholesky factor with a small diagonal jitter when needed, and :func:`floor_position` may floor
the position variances (a window on an image cannot place a target better than its pixel).

**Velocity by conditioning (ours).** The likelihood of eq. (13) looks only at a particle's position,
so in the exact posterior the velocity given the position is what the prediction says it is:
``p(v | p, y) = p(v | p)``. :func:`condition_velocity` therefore takes the position moments from
the weighted particles (eq. 8) and the velocity moments from the predicted Gaussian's conditional,
which is eq. 8's posterior in expectation but without its Monte Carlo error (Rao-Blackwellisation).
It matters with multiplicative fusion: its product of five cues puts most weight on a handful of
particles, whose velocities would become the track's with a velocity spread of a few cm/s, and the
next prediction would miss the target (measured: ``docs/experiments/2026-11-21-fls-gpf-study.md``).
"""
from __future__ import annotations

import functools

import numpy as np

from sonar_tracking.core.tracking.motion import ConstantVelocity
from sonar_tracking.core.tracking.noise import white_noise_acceleration

__all__ = ['sample_gaussian', 'weighted_moments', 'motion_matrices', 'propagate', 'predict', 'floor_position',
           'condition_velocity', 'kalman_update']

_CV = ConstantVelocity(2)


def _factor(cov: np.ndarray) -> np.ndarray:
    """A Cholesky factor of ``cov``, jittered into positive definiteness if it is not."""
    c = 0.5 * (cov + cov.T)
    try:
        return np.linalg.cholesky(c)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(c)
        floor = max(float(w.max()), 1e-12) * 1e-9
        return v * np.sqrt(np.maximum(w, floor))


def sample_gaussian(mean: np.ndarray, cov: np.ndarray, k: int, rng: np.random.Generator | None = None,
                    z: np.ndarray | None = None) -> np.ndarray:
    """``k`` draws ``(k, n)`` of ``N(mean, cov)``, from ``rng`` or from given standard normal
    numbers ``z (k, n)``."""
    if z is None:
        if rng is None:
            raise ValueError('sample_gaussian needs rng or z')
        z = rng.standard_normal((k, mean.size))
    return mean[None, :] + z @ _factor(cov).T


def weighted_moments(particles: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of particles ``(K, n)``: with normalised ``weights`` the posterior
    moments of the update (eq. 8, step 2 of §4.2.3), without them eqs. (10)-(11) (1/K)."""
    if weights is None:
        weights = np.full(len(particles), 1.0 / len(particles))
    mean = weights @ particles
    dev = particles - mean
    cov = (dev * weights[:, None]).T @ dev
    return mean, 0.5 * (cov + cov.T)


def floor_position(cov: np.ndarray, variance: float) -> np.ndarray:
    """``cov`` with its position block's eigenvalues raised to at least ``variance``."""
    pos = cov[:2, :2]
    w, v = np.linalg.eigh(pos)
    if w.min() >= variance:
        return cov
    out = cov.copy()
    out[:2, :2] = (v * np.maximum(w, variance)) @ v.T
    return out


def condition_velocity(prior_mean: np.ndarray, prior_cov: np.ndarray, position: np.ndarray,
                       position_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The posterior ``(mean (4,), cov (4, 4))`` of a state ``[x, y, vx, vy]`` whose position has
    posterior moments ``position (2,)``, ``position_cov (2, 2)`` (eq. 8 on the weighted particles)
    and whose velocity follows the prior ``N(prior_mean, prior_cov)`` given the position (module
    docstring): with ``G = P_vp P_pp^-1``, the velocity mean is ``m_v + G (position - m_p)``, its
    covariance ``P_vv - G P_pv + G position_cov G^T`` and its cross-covariance with the position
    ``G position_cov``. A prior without position uncertainty leaves the velocity as it is."""
    m, P = np.asarray(prior_mean, dtype=np.float64), np.asarray(prior_cov, dtype=np.float64)
    pos, pcov = np.asarray(position, dtype=np.float64), np.asarray(position_cov, dtype=np.float64)
    try:
        G = np.linalg.solve(P[:2, :2], P[:2, 2:]).T
    except np.linalg.LinAlgError:
        G = np.zeros((2, 2))
    mean = np.concatenate([pos, m[2:] + G @ (pos - m[:2])])
    cov = np.empty((4, 4))
    cov[:2, :2] = pcov
    cov[2:, :2] = G @ pcov
    cov[:2, 2:] = cov[2:, :2].T
    cov[2:, 2:] = P[2:, 2:] - G @ P[:2, 2:] + G @ pcov @ G.T
    return mean, 0.5 * (cov + cov.T)


@functools.lru_cache(maxsize=8)
def _motion(dt: float, q: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``F``, ``Q`` and a factor of ``Q`` (None when ``Q`` is 0), read-only: every track of a frame
    shares them."""
    F, Q = _CV.transition(dt), white_noise_acceleration(dt, q)
    L = _factor(Q) if np.any(Q) else None
    for a in (F, Q, L):
        if a is not None:
            a.setflags(write=False)
    return F, Q, L


def motion_matrices(dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """``F`` (ESC eq. 3) and ``Q`` (white-noise acceleration of PSD ``q``) over ``dt`` seconds
    (read-only arrays)."""
    return _motion(float(dt), float(q))[:2]


def propagate(particles: np.ndarray, F: np.ndarray, Q: np.ndarray, rng: np.random.Generator,
              factor: np.ndarray | None = None) -> np.ndarray:
    """Sample ``p(x_{t+1} | x_n)`` for every particle ``(K, 4)``: ``F x_n + w_n``, ``w_n ~ N(0, Q)``
    (``factor``: a Cholesky factor of ``Q``, if the caller has it)."""
    if not np.any(Q):
        noise = 0.0
    else:
        noise = rng.standard_normal(particles.shape) @ (_factor(Q) if factor is None else factor).T
    return particles @ F.T + noise


def predict(mean: np.ndarray, cov: np.ndarray, dt: float, q: float, k: int, rng: np.random.Generator
            ) -> tuple[np.ndarray, np.ndarray]:
    """GPF time update (eqs. 9-12): sample the posterior, move each particle by the motion model,
    and return the predicted mean (eq. 10) and covariance (eq. 11)."""
    F, Q, L = _motion(float(dt), float(q))
    moved = propagate(sample_gaussian(mean, cov, k, rng), F, Q, rng, L)
    return weighted_moments(moved)


def kalman_update(mean: np.ndarray, cov: np.ndarray, innovation: np.ndarray, H: np.ndarray, R: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The (extended) Kalman measurement update for one track: gain ``K = P H^T (H P H^T + R)^-1``,
    ``x + K nu`` and the Joseph form ``(I - K H) P (I - K H)^T + K R K^T`` (symmetric, positive
    definite even with rounding). ``H`` is the measurement matrix or, for the EKF, the Jacobian."""
    S = H @ cov @ H.T + R
    K = np.linalg.solve(S, H @ cov).T
    I_KH = np.eye(len(mean)) - K @ H
    new = I_KH @ cov @ I_KH.T + K @ R @ K.T
    return mean + K @ innovation, 0.5 * (new + new.T)

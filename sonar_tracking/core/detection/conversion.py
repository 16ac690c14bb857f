"""Converted measurements: sensor range and bearing to world Cartesian position and covariance.

The ESC paper's conversion (eqs. 8-10): ``z = [r cos(theta), r sin(theta)]`` and
``R = J W J^T`` with ``W = diag(sigma_r^2, sigma_theta^2)`` (eq. 7) and ``J`` the Jacobian of
eq. (10), bearings taken in the world frame (sensor bearing + sensor yaw), positions offset by the
sensor position.

Option ``unbiased``: the unbiased converted measurement of ref. [23] (Mo, Song, Zhou, Sun and
Bar-Shalom, IEEE TAES 34(3), 1998): with ``l = exp(-sigma_theta^2 / 2)`` and ``l2 = l^4``::

    z_u = [r cos(theta), r sin(theta)] / l
    R_u11 = (l^-2 - 2) r^2 cos^2(theta) + (r^2 + sigma_r^2) (1 + l2 cos(2 theta)) / 2
    R_u22 = (l^-2 - 2) r^2 sin^2(theta) + (r^2 + sigma_r^2) (1 - l2 cos(2 theta)) / 2
    R_u12 = (l^-2 - 2) r^2 cos(theta) sin(theta) + (r^2 + sigma_r^2) l2 sin(2 theta) / 2

(the measurement-conditioned form, evaluated at the measured range and bearing).
"""
from __future__ import annotations

import numpy as np

__all__ = ['convert_measurements']


def convert_measurements(r: np.ndarray, theta: np.ndarray, sigma_r: float | np.ndarray,
                         sigma_theta: float | np.ndarray, pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
                         unbiased: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """World positions ``(N, 2)`` and covariances ``(N, 2, 2)`` of polar measurements.

    ``theta`` is the bearing in the sensor frame [rad]; ``pose = (x, y, yaw)`` the sensor in the world.
    """
    r = np.asarray(r, dtype=float)
    b = np.asarray(theta, dtype=float) + pose[2]
    c, s = np.cos(b), np.sin(b)
    sr2 = np.broadcast_to(np.asarray(sigma_r, dtype=float) ** 2, r.shape)
    st2 = np.broadcast_to(np.asarray(sigma_theta, dtype=float) ** 2, r.shape)
    cov = np.empty(r.shape + (2, 2))
    if unbiased:
        lam = np.exp(-st2 / 2.0)
        lam2 = lam ** 4
        k = lam ** -2 - 2.0
        q = (r * r + sr2) / 2.0
        xy = np.stack([r * c, r * s], axis=-1) / lam[..., None]
        cov[..., 0, 0] = k * r * r * c * c + q * (1.0 + lam2 * np.cos(2 * b))
        cov[..., 1, 1] = k * r * r * s * s + q * (1.0 - lam2 * np.cos(2 * b))
        cov[..., 0, 1] = cov[..., 1, 0] = k * r * r * c * s + q * lam2 * np.sin(2 * b)
    else:
        xy = np.stack([r * c, r * s], axis=-1)
        # R = J W J^T with J = [[c, -r s], [s, r c]] (eq. 10).
        rr = r * r * st2
        cov[..., 0, 0] = c * c * sr2 + s * s * rr
        cov[..., 1, 1] = s * s * sr2 + c * c * rr
        cov[..., 0, 1] = cov[..., 1, 0] = c * s * (sr2 - rr)
    xy[..., 0] += pose[0]
    xy[..., 1] += pose[1]
    return xy, cov

"""Process noise covariance ``Q`` of eq. (2) (the paper does not give it).

We use the continuous white-noise acceleration model (Bar-Shalom, Li & Kirubarajan 2001,
§6.2.2): acceleration is white noise of power spectral density ``q`` [m^2/s^3] in each axis,
which gives, per axis, ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``. Unlike the discrete
(piecewise-constant) variant it stays consistent when scans arrive at irregular intervals,
which a replayed bag or a mechanically scanned sonar produces. The same ``Q`` serves the CTR
models (the usual choice for known-rate turn models); ``q`` is set per model.
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.tracking.errors import TrackingInputError

__all__ = ['white_noise_acceleration']


def white_noise_acceleration(dt: float, q: float, ndim: int = 2) -> np.ndarray:
    """``Q`` of the continuous white-noise acceleration model for state ``[p (d), v (d)]``.

    Parameters
    ----------
    dt : time step [s], >= 0.
    q : acceleration power spectral density [m^2/s^3] per axis, >= 0.
    ndim : spatial dimension d.
    """
    if dt < 0 or q < 0:
        raise TrackingInputError(f'white_noise_acceleration needs dt >= 0 and q >= 0, got dt={dt}, q={q}')
    eye = np.eye(ndim)
    return q * np.block([[dt ** 3 / 3.0 * eye, dt ** 2 / 2.0 * eye],
                         [dt ** 2 / 2.0 * eye, dt * eye]])

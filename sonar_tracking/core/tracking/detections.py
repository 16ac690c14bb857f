"""Detection records (``DETECTION_DTYPE`` or any structured array with ``x, y``) to tracker input."""
from __future__ import annotations

import numpy as np

__all__ = ['detections_to_measurements']

_COV_FIELDS = ('cov_xx', 'cov_xy', 'cov_yy')


def detections_to_measurements(records: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, str]:
    """``(z (N, 2), R (N, 2, 2) or None, rho (N,) or None, note)`` from detection records.

    Only ``x`` and ``y`` are required (``ValueError`` otherwise). Without all three covariance
    fields ``R`` is None (the tracker then uses ``detection.sigma``), without ``clutter_density``
    ``rho`` is None (``clutter.density``); ``note`` says which were missing.
    """
    names = set(records.dtype.names or ())
    if not {'x', 'y'} <= names:
        raise ValueError(f'detections need fields x and y; the cloud has {sorted(names)}')
    flat = records.reshape(-1)
    z = np.column_stack((flat['x'].astype(float), flat['y'].astype(float)))
    notes = []
    R = None
    if set(_COV_FIELDS) <= names:
        R = np.empty((len(flat), 2, 2))
        R[:, 0, 0] = flat['cov_xx']
        R[:, 0, 1] = R[:, 1, 0] = flat['cov_xy']
        R[:, 1, 1] = flat['cov_yy']
    else:
        notes.append('no covariance fields: using detection.sigma')
    rho = flat['clutter_density'].astype(float) if 'clutter_density' in names else None
    if rho is None:
        notes.append('no clutter_density field: using clutter.density')
    return z, R, rho, '; '.join(notes)

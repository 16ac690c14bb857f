"""Record dtypes of the PointCloud2 topics (DESIGN §4): one constant per topic.

Defined here so that core components produce records directly; ``sonar_tracking.msgs`` re-exports them
as the message contract. All are packed, little-endian, height-1 clouds. Positions and covariances are float64 because
world coordinates of a harbour sonar run to kilometres and covariances span many decades.
"""
from __future__ import annotations

import numpy as np

__all__ = ['DETECTION_DTYPE', 'TRACK_DTYPE', 'TRUTH_DTYPE', 'REGION_DTYPE', 'GPF_TRACK_DTYPE',
           'FEATURE_NAMES', 'RECORD_DTYPES']

_F8 = '<f8'

#: ``/detections``: world position, sensor polar position, amplitude, SCMDE density, covariance.
DETECTION_DTYPE = np.dtype([
    ('x', _F8), ('y', _F8), ('range', _F8), ('bearing', _F8), ('amplitude', _F8),
    ('clutter_density', _F8), ('cov_xx', _F8), ('cov_xy', _F8), ('cov_yy', _F8),
])

#: ``/tracks``: IMM-IPDA track state, existence probability and mode probabilities.
TRACK_DTYPE = np.dtype([
    ('track_id', '<u4'), ('x', _F8), ('y', _F8), ('vx', _F8), ('vy', _F8), ('existence', _F8),
    ('confirmed', 'u1'), ('mode_cv', _F8), ('mode_ccw', _F8), ('mode_cw', _F8),
    ('cov_xx', _F8), ('cov_xy', _F8), ('cov_yy', _F8), ('cov_vxvx', _F8), ('cov_vyvy', _F8),
])

#: ``/sonar/truth``: simulator ground truth.
TRUTH_DTYPE = np.dtype([
    ('target_id', '<u4'), ('x', _F8), ('y', _F8), ('vx', _F8), ('vy', _F8),
])

#: Names of the 30 region features, numbered as in FLS paper Table 2.
FEATURE_NAMES = tuple(f'f{i:02d}' for i in range(1, 31))

#: ``/fls/regions``: one record per segmented region, then features f01..f30.
REGION_DTYPE = np.dtype(
    [('region_id', '<u4'), ('x', _F8), ('y', _F8), ('range', _F8), ('bearing', _F8)]
    + [(name, _F8) for name in FEATURE_NAMES])

#: ``/gpf/tracks``: GPF track state, fusion mode in use (0 = MF, 1 = WF), covariance.
GPF_TRACK_DTYPE = np.dtype([
    ('track_id', '<u4'), ('x', _F8), ('y', _F8), ('vx', _F8), ('vy', _F8), ('confirmed', 'u1'),
    ('fusion', 'u1'), ('cov_xx', _F8), ('cov_xy', _F8), ('cov_yy', _F8), ('cov_vxvx', _F8),
    ('cov_vyvy', _F8),
])

#: Topic name -> record dtype.
RECORD_DTYPES = {
    '/detections': DETECTION_DTYPE,
    '/tracks': TRACK_DTYPE,
    '/sonar/truth': TRUTH_DTYPE,
    '/fls/regions': REGION_DTYPE,
    '/gpf/tracks': GPF_TRACK_DTYPE,
}

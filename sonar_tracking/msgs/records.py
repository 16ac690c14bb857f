"""Record dtypes of the PointCloud2 topics (DESIGN §4), defined once in ``sonar_tracking.core.records``."""
from sonar_tracking.core.records import (
                                         DETECTION_DTYPE,
                                         FEATURE_NAMES,
                                         GPF_TRACK_DTYPE,
                                         RECORD_DTYPES,
                                         REGION_DTYPE,
                                         TRACK_DTYPE,
                                         TRUTH_DTYPE,
)

__all__ = ['DETECTION_DTYPE', 'TRACK_DTYPE', 'TRUTH_DTYPE', 'REGION_DTYPE', 'GPF_TRACK_DTYPE', 'FEATURE_NAMES',
           'RECORD_DTYPES']

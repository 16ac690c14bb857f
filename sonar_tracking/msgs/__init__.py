"""Conversions between ROS 2 messages and numpy / core records, by field name.

Reading works on rclpy messages and on ``rosbags`` dataclasses alike; building messages goes
through a :class:`~sonar_tracking.msgs.types.MessageTypes` (rclpy by default, or a rosbags typestore).
Every conversion error is an :class:`AdapterError` whose text says what is wrong.
"""
from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.image import ENCODING_DTYPES, array_to_image, image_to_array
from sonar_tracking.msgs.markers import covariance_ellipse, track_markers
from sonar_tracking.msgs.odometry import odometry_to_pose, pose_to_odometry
from sonar_tracking.msgs.pairing import GIVEN_UP, StampPairer
from sonar_tracking.msgs.pointcloud import array_to_cloud, cloud_to_array, dtype_to_fields, fields_to_dtype
from sonar_tracking.msgs.projected import PROJECTED_TYPE, sector_to_projected
from sonar_tracking.msgs.records import (
                      DETECTION_DTYPE,
                      FEATURE_NAMES,
                      GPF_TRACK_DTYPE,
                      RECORD_DTYPES,
                      REGION_DTYPE,
                      TRACK_DTYPE,
                      TRUTH_DTYPE,
)
from sonar_tracking.msgs.sector import (
                      SectorPair,
                      SectorPairer,
                      geometry_to_scan,
                      scan_to_geometry,
                      sector_from_messages,
)
from sonar_tracking.msgs.stamps import header, header_ns, ns_to_stamp, stamp_to_ns
from sonar_tracking.msgs.types import MessageTypes, RclpyTypes, RosbagsTypes, rclpy_types

__all__ = [
    'AdapterError', 'PROJECTED_TYPE', 'sector_to_projected',
    'ENCODING_DTYPES', 'image_to_array', 'array_to_image',
    'array_to_cloud', 'cloud_to_array', 'dtype_to_fields', 'fields_to_dtype',
    'DETECTION_DTYPE', 'TRACK_DTYPE', 'TRUTH_DTYPE', 'REGION_DTYPE', 'GPF_TRACK_DTYPE',
    'FEATURE_NAMES', 'RECORD_DTYPES',
    'SectorPair', 'SectorPairer', 'geometry_to_scan', 'scan_to_geometry', 'sector_from_messages',
    'StampPairer', 'GIVEN_UP',
    'track_markers', 'covariance_ellipse', 'odometry_to_pose', 'pose_to_odometry',
    'header', 'header_ns', 'ns_to_stamp', 'stamp_to_ns',
    'MessageTypes', 'RclpyTypes', 'RosbagsTypes', 'rclpy_types',
]

"""``sonar_view``: the pipeline's messages as a Rerun recording, served to a browser on this machine.

:mod:`.scene` turns messages (rclpy or rosbags, read by field name through ``sonar_tracking.msgs``) into
Rerun entities; :mod:`sonar_tracking.cli.sonar_view` feeds it from live topics or a bag and
serves the recording. Rerun is an extra (``requirements-view.txt``), never needed by the nodes.
"""

__all__ = ['TOPICS', 'IMAGE_TOPICS', 'RECORD_TOPICS']

#: Relative topic name -> ROS message type, every topic the view understands.
TOPICS: dict[str, str] = {
    'sonar/sector': 'sensor_msgs/msg/Image',
    'sonar/sector_info': 'sensor_msgs/msg/LaserScan',
    'platform/odometry': 'nav_msgs/msg/Odometry',
    'sonar/truth': 'sensor_msgs/msg/PointCloud2',
    'detections': 'sensor_msgs/msg/PointCloud2',
    'detector/threshold': 'std_msgs/msg/Float64',
    'detector/clutter_density': 'std_msgs/msg/Float64',
    'tracks': 'sensor_msgs/msg/PointCloud2',
    'fls/image': 'sensor_msgs/msg/Image',
    'fls/image_info': 'nav_msgs/msg/MapMetaData',
    'fls/regions': 'sensor_msgs/msg/PointCloud2',
    'gpf/tracks': 'sensor_msgs/msg/PointCloud2',
}
#: The large ones: a live view takes them best effort (it may skip some, never slows a publisher).
IMAGE_TOPICS = frozenset({'sonar/sector', 'sonar/sector_info', 'fls/image', 'fls/image_info'})
#: The per-scan records and the plotted scalars, which ``--record-period`` thins.
RECORD_TOPICS = frozenset(set(TOPICS) - IMAGE_TOPICS - {'platform/odometry'})

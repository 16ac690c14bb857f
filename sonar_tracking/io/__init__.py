"""Files in and out, without ROS: rosbag2 bags (:mod:`.bags`) and recordings of real sonars
(:mod:`.importers`). Nothing here imports rclpy; QoS conversion to rclpy lives in ``sonar_tracking.ros``."""

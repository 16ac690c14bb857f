"""Algorithms of sonar_tracking, free of ROS: nothing under ``core`` imports rclpy or a message package."""

"""rclpy nodes of sonar_tracking: thin wrappers, adapter -> core -> adapter -> publish."""

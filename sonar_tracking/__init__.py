"""sonar_tracking: an AUV sonar tracking stack for ROS 2 Jazzy.

``sonar_tracking.core`` holds the algorithms (pure numpy/scipy/OpenCV, never ROS);
``sonar_tracking.nodes`` the thin rclpy nodes; ``sonar_tracking.cli`` the command-line programs.
"""

__all__ = ['__version__']

__version__ = '0.1.0'

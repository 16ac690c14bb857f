"""sonar_tracking: an AUV sonar tracking stack for ROS 2 Jazzy.

One folder per role (``docs/architecture.md``): ``core`` the runtime algorithms (numpy, scipy,
OpenCV, numba; never ROS), ``sim`` the simulator, ``studies`` metrics and paper reproductions,
``msgs`` message conversions, ``io`` bags and recordings, ``ros`` what every node needs, ``nodes``
the thin rclpy nodes, ``cli`` the command-line programs.
"""

__all__ = ['__version__']

__version__ = '0.1.0'

"""``sonar_view``: the pipeline's messages as a Rerun recording, served to a browser on this machine.

:mod:`.scene` turns messages (rclpy or rosbags, read by field name through ``msg_adapters``) into
Rerun entities; :mod:`sonar_tracking.tools.sonar_view` feeds it from live topics or a bag and
serves the recording. Rerun is an extra (``requirements-view.txt``), never needed by the nodes.
"""

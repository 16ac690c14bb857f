"""Command-line programs of sonar_tracking: the entry points (``sonar_stack``, ``sonar_eval``, ``bag_record``,
``bag_replay``, ``sonar_import``, ``sonar_echo``, ``sonar_view``), the bench harness and its cases, and the
study front ends."""

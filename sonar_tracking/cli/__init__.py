"""Command-line programs of sonar_tracking (``sonar_eval`` and, later, the stack and bag tools)."""

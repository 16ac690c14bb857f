"""Benchmark cases for ``sonar_eval bench``; every module here registers its cases on import."""

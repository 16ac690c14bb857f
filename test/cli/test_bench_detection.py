"""The imaging detector's bench cases render their frames, run the Oculus preset on them and report
each frame's time beside the median."""
from __future__ import annotations

from sonar_tracking.cli import bench


def test_the_moving_imaging_frame_case_runs_and_reports_per_frame_figures():
    # The static case differs only in the pose it passes; both are registered by one loop.
    assert 'detection.imaging_frame' in bench.cases()
    case = bench.cases()['detection.imaging_frame_moving']
    r = bench.run_case(case, repeats=3)   # renders 512 x 1000 frames, warms the detector up, times 3
    assert r.repeats == 3 and 0 < r.min_s <= r.median_s <= r.max_s
    figures = case.derived(r)
    assert figures['frames'] == 3 and figures['p99_ms'] >= 1e3 * r.median_s > 0.0

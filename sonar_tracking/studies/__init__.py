"""Evaluation: tracking performance measures (ESC paper §5, FLS paper eq. 19, OSPA, GOSPA)."""
from sonar_tracking.studies.metrics import (
                      TAU_FALSE,
                      TAU_TRUE,
                      GospaResult,
                      MetricError,
                      OspaResult,
                      ScanEvaluation,
                      TrackClasses,
                      center_location_error,
                      classify_tracks,
                      confirmed_false_track_rate,
                      confirmed_true_track_rate,
                      evaluate_scan,
                      ftd_distances,
                      gospa,
                      ospa,
                      position_rmse,
)

__all__ = ['TAU_FALSE', 'TAU_TRUE', 'GospaResult', 'MetricError', 'OspaResult', 'ScanEvaluation', 'TrackClasses',
           'classify_tracks', 'confirmed_false_track_rate', 'confirmed_true_track_rate', 'evaluate_scan',
           'ftd_distances', 'gospa', 'ospa', 'position_rmse', 'center_location_error']

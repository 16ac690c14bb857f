"""Evaluation: tracking performance measures (ESC paper §5, OSPA, GOSPA)."""
from .metrics import (TAU_FALSE, TAU_TRUE, GospaResult, MetricError, OspaResult, ScanEvaluation, TrackClasses,
                      classify_tracks, confirmed_false_track_rate, confirmed_true_track_rate, evaluate_scan,
                      ftd_distances, gospa, ospa, position_rmse)

__all__ = ['TAU_FALSE', 'TAU_TRUE', 'GospaResult', 'MetricError', 'OspaResult', 'ScanEvaluation', 'TrackClasses',
           'classify_tracks', 'confirmed_false_track_rate', 'confirmed_true_track_rate', 'evaluate_scan',
           'ftd_distances', 'gospa', 'ospa', 'position_rmse']

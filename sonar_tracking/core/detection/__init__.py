"""Active-sonar detection (ESC paper §2-§4): cell thresholding, converted measurements, SCMDE, ESC."""
from sonar_tracking.core.detection.cells import CellDetections, threshold_cells
from sonar_tracking.core.detection.conversion import convert_measurements
from sonar_tracking.core.detection.desired_density import DesiredDensityTable, TableError, resolve_desired_density
from sonar_tracking.core.detection.detector import (
                       ActiveDetector,
                       CellConfig,
                       DetectionInputError,
                       DetectorConfig,
                       EscConfig,
                       ScanResult,
                       ScmdeConfig,
                       ThresholdConfig,
                       best_track_focus,
                       tracked_positions,
)
from sonar_tracking.core.detection.esc import ExtremumSeekingController, compandor, sign_block
from sonar_tracking.core.detection.scmde import PolarWindow, scmde

__all__ = ['CellDetections', 'threshold_cells', 'convert_measurements', 'DesiredDensityTable', 'TableError',
           'ActiveDetector', 'CellConfig', 'DetectionInputError', 'DetectorConfig', 'EscConfig', 'ScanResult',
           'ScmdeConfig', 'ThresholdConfig', 'ExtremumSeekingController', 'compandor', 'sign_block',
           'PolarWindow', 'scmde', 'resolve_desired_density', 'best_track_focus',
           'tracked_positions']

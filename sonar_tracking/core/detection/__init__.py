"""Active-sonar detection (ESC paper §2-§4): cell thresholding, converted measurements, SCMDE, ESC."""
from .cells import CellDetections, threshold_cells
from .conversion import convert_measurements
from .desired_density import DesiredDensityTable, TableError, resolve_desired_density
from .detector import (ActiveDetector, CellConfig, DetectionInputError, DetectorConfig, EscConfig, ScanResult,
                       ScmdeConfig, ThresholdConfig, best_track_focus)
from .esc import ExtremumSeekingController, compandor, sign_block
from .scmde import PolarWindow, scmde

__all__ = ['CellDetections', 'threshold_cells', 'convert_measurements', 'DesiredDensityTable', 'TableError',
           'ActiveDetector', 'CellConfig', 'DetectionInputError', 'DetectorConfig', 'EscConfig', 'ScanResult',
           'ScmdeConfig', 'ThresholdConfig', 'ExtremumSeekingController', 'compandor', 'sign_block',
           'PolarWindow', 'scmde', 'resolve_desired_density', 'best_track_focus']

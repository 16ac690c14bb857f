"""Forward-looking-sonar front end (FLS paper §2-§3): image building, the modified median filter,
region growing, the 30 region features of Table 2, GRNN classification and SFS/SBS selection."""
from sonar_tracking.core.fls.features import FEATURE_LABELS, N_FEATURES, FeatureConfig, patch_features, region_features
from sonar_tracking.core.fls.filters import FilterConfig, PolarSweepFilter, median_blur, trimmed_mean
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.fls.image import ImageBuilder, ImageConfig, canvas_for, grid_image
from sonar_tracking.core.fls.pipeline import (
           FlsConfig,
           FlsFrame,
           FlsInputError,
           FlsProcessor,
           check_sector,
           regions_to_records,
)
from sonar_tracking.core.fls.segmentation import SegmentConfig, cells_per_pixel, grow_regions, threshold_components
from sonar_tracking.core.fls.sweep import SweepTracker
from sonar_tracking.core.fls.windows import WindowImage, window_features

#: The features the paper selects by SFS (Table 7), in the order found: M7, M4, mean intensity,
#: background mean, inverse difference moment. The GPF tracker's default feature set.
PAPER_FEATURES = (20, 17, 3, 6, 24)

__all__ = ['PAPER_FEATURES', 'FEATURE_LABELS', 'FeatureConfig', 'N_FEATURES', 'patch_features', 'region_features',
           'FilterConfig', 'PolarSweepFilter', 'median_blur', 'trimmed_mean', 'ImageGrid', 'ImageBuilder',
           'ImageConfig', 'canvas_for', 'grid_image', 'FlsConfig', 'FlsFrame', 'FlsInputError', 'FlsProcessor',
           'check_sector', 'regions_to_records', 'SegmentConfig', 'cells_per_pixel', 'grow_regions',
           'threshold_components', 'SweepTracker', 'WindowImage', 'window_features']

"""Forward-looking-sonar front end (FLS paper §2-§3): image building, the modified median filter,
region growing, the 30 region features of Table 2, GRNN classification and SFS/SBS selection."""
from .features import FEATURE_LABELS, FeatureConfig, N_FEATURES, patch_features, region_features
from .filters import FilterConfig, PolarSweepFilter, median_blur, trimmed_mean
from .grid import ImageGrid
from .image import ImageBuilder, ImageConfig, canvas_for, grid_image
from .pipeline import FlsConfig, FlsFrame, FlsInputError, FlsProcessor, check_sector, regions_to_records
from .segmentation import SegmentConfig, cells_per_pixel, grow_regions, threshold_components
from .sweep import SweepTracker
from .windows import WindowImage, window_features

#: The features the paper selects by SFS (Table 7), in the order found: M7, M4, mean intensity,
#: background mean, inverse difference moment. The GPF tracker's default feature set.
PAPER_FEATURES = (20, 17, 3, 6, 24)

__all__ = ['PAPER_FEATURES', 'FEATURE_LABELS', 'FeatureConfig', 'N_FEATURES', 'patch_features', 'region_features',
           'FilterConfig', 'PolarSweepFilter', 'median_blur', 'trimmed_mean', 'ImageGrid', 'ImageBuilder',
           'ImageConfig', 'canvas_for', 'grid_image', 'FlsConfig', 'FlsFrame', 'FlsInputError', 'FlsProcessor',
           'check_sector', 'regions_to_records', 'SegmentConfig', 'cells_per_pixel', 'grow_regions',
           'threshold_components', 'SweepTracker', 'WindowImage', 'window_features']

"""The fls/image + fls/image_info message rules (sonar_tracking.msgs.map_info)."""
import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.msgs.map_info import fls_image, grid_to_map_info, map_info_to_grid


def test_the_message_rule_checks_encoding_size_and_nan():
    img = np.ones((4, 5), np.float32)
    assert fls_image(ma.array_to_image(img, '32FC1'), (4, 5)).dtype == np.float32
    with pytest.raises(ma.AdapterError, match='32FC1'):
        fls_image(ma.array_to_image(img.astype(np.uint8), 'mono8'), (4, 5))
    with pytest.raises(ma.AdapterError, match='image_info says'):
        fls_image(ma.array_to_image(img, '32FC1'), (5, 4))
    img[1, 1] = np.nan
    with pytest.raises(ma.AdapterError, match='NaN'):
        fls_image(ma.array_to_image(img, '32FC1'), (4, 5))


@pytest.mark.parametrize('grid, match', [
    (ImageGrid(resolution=1e-9, width=400, height=400, origin_x=0.0, origin_y=0.0), 'resolution'),
    (ImageGrid(resolution=0.1, width=8000, height=8000, origin_x=0.0, origin_y=0.0), 'more than'),
])
def test_image_info_beyond_physical_bounds_is_refused(grid, match):
    with pytest.raises(ma.AdapterError, match=match):
        map_info_to_grid(grid_to_map_info(grid, 0))

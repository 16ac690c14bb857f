"""Inputs that once crashed the GPF tracker or made it refuse every frame, and tracks that leave
the sensor's coverage."""
from __future__ import annotations

import numpy as np
import pytest

from sonar_tracking.core.fls.windows import WindowImage


@pytest.mark.parametrize('size', [3, 9, 31])
def test_window_patches_at_and_beyond_every_edge_read_the_right_pixels(size):
    # Regression: a particle just outside the image (within a window of its edge) indexed one past
    # the padded image's end (IndexError) or wrapped into the next row's pixels.
    rng = np.random.default_rng(size)
    img = rng.random((23, 17)) + 0.5
    wi = WindowImage(img, max_size=size)
    half = size // 2 + 1
    big = np.pad(img, 3 * size)              # zero (no data) outside the image
    rows, cols = np.meshgrid(np.arange(-2 * size, 23 + 2 * size), np.arange(-2 * size, 17 + 2 * size),
                             indexing='ij')
    rows, cols = rows.ravel(), cols.ravel()
    got = wi.patches(rows, cols, size)
    for k, (r, c) in enumerate(zip(rows, cols)):
        want = big[r + 3 * size - half:r + 3 * size + half + 1, c + 3 * size - half:c + 3 * size + half + 1]
        np.testing.assert_array_equal(got[k], want)
    assert np.isfinite(wi.features(rows, cols, size, (3, 6, 17, 20, 24))).all()

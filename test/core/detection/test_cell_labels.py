"""Labelling of above-threshold cells (core/detection/cells.py): the joining of sparse cells and the
dilation of dense frames against the plain image labelling (maximum filter, then ndimage.label)."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from scipy import ndimage

from sonar_tracking.core.detection import cells
from sonar_tracking.core.detection.cells import label_cells, threshold_cells


def _image_labels(mask: np.ndarray, merge_bins: int, merge_beams: int) -> tuple[np.ndarray, int]:
    """Each cell widened to a ``(merge - 1)``-cell box by a maximum filter, the boxes' 8-connected
    (line-connected where one merge size is 1) components labelled, the labels kept on the cells."""
    if merge_bins <= 1 and merge_beams <= 1:
        labels = np.zeros(mask.shape, np.int32)
        labels[mask] = np.arange(1, np.count_nonzero(mask) + 1)
        return labels, int(np.count_nonzero(mask))
    grown = ndimage.maximum_filter(mask, size=(max(merge_bins - 1, 1), max(merge_beams - 1, 1)), mode='constant',
                                   cval=False)
    structure = np.zeros((3, 3), bool)
    structure[1, 1] = True
    if merge_bins > 1:
        structure[:, 1] = True
    if merge_beams > 1:
        structure[1, :] = True
    if merge_bins > 1 and merge_beams > 1:
        structure[:] = True
    labels, n = ndimage.label(grown, structure=structure)
    labels[~mask] = 0
    return labels, int(n)


def _masks(seed: int, count: int):
    """Masks of every kind: scattered cells, rows of cells, blocks, cells on the borders; merge sizes
    1-14, odd and even."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        shape = (int(rng.integers(1, 70)), int(rng.integers(1, 70)))
        mask = rng.random(shape) < float(rng.choice([0.002, 0.01, 0.04, 0.2]))
        kind = rng.integers(0, 4)
        if kind == 1:
            mask[rng.integers(0, shape[0]), :] = True
        elif kind == 2:
            r, c = rng.integers(0, shape[0]), rng.integers(0, shape[1])
            mask[r:r + 5, c:c + 7] = True
        elif kind == 3:
            mask[0, 0] = mask[-1, -1] = mask[0, -1] = mask[-1, 0] = True
        yield mask, int(rng.integers(0, 15)), int(rng.integers(0, 15))


@pytest.mark.parametrize('sparse', [True, False], ids=['joined cells', 'dilated image'])
def test_labels_at_the_cells_equal_the_image_labelling(sparse, monkeypatch):
    """Both ways give every cell the image labelling's label, numbered as ndimage.label numbers
    them (row-major order of each component's first pixel), and the same count."""
    monkeypatch.setattr(cells, '_SPARSE', 10 ** 9 if sparse else 0)
    for mask, mb, mw in _masks(91, 400):
        rows, cols = np.nonzero(mask)
        expected, n = _image_labels(mask, mb, mw)
        labels, m = cells._labels_at(mask, rows, cols, mb, mw)
        assert m == n and np.array_equal(labels, expected[rows, cols]), (mask.shape, mb, mw)
        full, m = label_cells(mask, mb, mw)
        assert m == n and np.array_equal(full, expected) and full.dtype == expected.dtype


def test_threshold_cells_of_a_sparse_imaging_frame_need_no_frame_sized_labels(monkeypatch):
    """A 512-beam x 1000-bin CFAR frame with tens of cells above the threshold (the Oculus preset's
    connected blobs over 10 x 12 cells): the cells are joined directly, without an image pass of
    their own (only the above-threshold mask is frame-sized), into the image labelling's groups."""
    rng = np.random.default_rng(93)
    q = rng.standard_exponential((1000, 512)).astype(np.float32)
    q[rng.integers(0, 1000, 40), rng.integers(0, 512, 40)] = 50.0
    q[400:404, 200:206] = 50.0                      # a blob
    q[409, 215] = 50.0                              # and one within merge distance of it
    expected, n = _image_labels(q > 20.0, 10, 12)
    threshold_cells(q, 20.0, 10, 12, connected=True)
    monkeypatch.setattr(ndimage, 'label', None)     # no image labelling may run
    tracemalloc.start()
    try:
        found = threshold_cells(q, 20.0, 10, 12, connected=True)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert found.n_echoes == n == len(found) and np.array_equal(found.cell_echo + 1,
                                                                 expected[found.cell_rows, found.cell_cols])
    assert peak < q.size + 2 ** 17, peak

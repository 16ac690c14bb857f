"""Cell detection: every cell of a sector above the threshold ``tau`` becomes a detection.

Adjacent cells above threshold are merged into one detection (amplitude-weighted centroid, peak
amplitude) only where the sensor's resolution says they are one echo: when a resolution cell spans
several image cells. ``merge_bins`` x ``merge_beams`` is the size of a resolution cell in image
cells: cells closer than that in both directions are joined (connected components with that
neighbourhood). The harbour sonar's image cells *are* its resolution cells (1 x 1): every cell is
its own detection, as the ESC paper's clutter model assumes (independent cells, eq. 16). A SeaKing
echo spreads over about ``beam_width / step`` beams and ``pulse_length / bin`` bins, so e.g. 2 x 2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ['CellDetections', 'threshold_cells']


@dataclass(frozen=True, eq=False)
class CellDetections:
    """Detections in image coordinates: fractional row (bin) and column (beam) indices, peak amplitude."""

    rows: np.ndarray
    cols: np.ndarray
    amplitude: np.ndarray

    def __len__(self) -> int:
        return len(self.amplitude)


def threshold_cells(amplitudes: np.ndarray, tau: float, merge_bins: int = 1, merge_beams: int = 1) -> CellDetections:
    """Cells with amplitude ``> tau`` (ESC eq. 16's event), merged per resolution cell.

    Raises ValueError for a non-finite amplitude (callers validate first and drop the sector).
    """
    a = np.asarray(amplitudes)
    above = a > tau
    if merge_bins <= 1 and merge_beams <= 1:
        rows, cols = np.nonzero(above)
        return CellDetections(rows.astype(float), cols.astype(float), a[rows, cols].astype(float))
    structure = np.ones((2 * merge_bins - 1, 2 * merge_beams - 1), dtype=bool)
    labels, n = ndimage.label(above, structure=structure)
    if n == 0:
        empty = np.zeros(0)
        return CellDetections(empty, empty, empty)
    rows, cols = np.nonzero(labels)
    lab = labels[rows, cols] - 1
    w = a[rows, cols].astype(float)
    total = np.bincount(lab, weights=w, minlength=n)
    r = np.bincount(lab, weights=w * rows, minlength=n) / total
    c = np.bincount(lab, weights=w * cols, minlength=n) / total
    peak = np.zeros(n)
    np.maximum.at(peak, lab, w)
    return CellDetections(r, c, peak)

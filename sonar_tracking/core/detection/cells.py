"""Cell detection: cells of a sector above the threshold ``tau`` become detections.

Two groupings (``cells.grouping``):

* ``cells`` (the default, the ESC paper): every cell above the threshold is a detection, as the
  paper's clutter model assumes (independent cells, eq. 16), except that cells within one
  resolution cell of each other are one echo when a resolution cell spans several image cells:
  ``merge_bins`` x ``merge_beams`` is its size in image cells, and cells closer than that in both
  directions are joined (a SeaKing echo spreads over about ``beam_width / step`` beams and
  ``pulse_length / bin`` bins, so e.g. 2 x 2; the harbour sonar's image cells *are* its resolution
  cells, 1 x 1).
* ``connected``: one detection per connected group of above-threshold cells (8-connected), groups
  closer than ``merge_bins`` x ``merge_beams`` joined as well. An extended echo (a hull, a wall, a
  school of fish) is one detection instead of hundreds, which bounds the tracker's work on real
  data.

Either way a detection is at the amplitude-weighted centroid of its cells, with the peak amplitude,
and remembers how many range bins and beams it spans (its covariance grows with that extent, see
:mod:`.detector`). Every above-threshold cell also carries the label of its *connected echo* (its
8-connected component, joined over the merge distance), the unit that static-structure rejection
judges (:mod:`sonar_tracking.core.structure`); in ``connected`` grouping echoes and detections are
the same.

"Closer than m cells" for any merge size is computed without a large structuring element: every
cell is widened to a box of ``m - 1`` cells (1 where ``m = 1``) and the boxes' 8-connected (or, where
one direction has ``m = 1``, line-connected) components are taken: two boxes touch or overlap
exactly when their cells are at most ``m - 1`` apart in that direction.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ['CellDetections', 'threshold_cells', 'label_cells']


@dataclass(frozen=True, eq=False)
class CellDetections:
    """Detections in image coordinates and the above-threshold cells they came from.

    ``rows``, ``cols``: fractional row (bin) and column (beam) of each detection; ``amplitude`` its
    peak; ``span_rows``, ``span_cols`` the number of bins and beams it spans (1 for a single cell).
    ``cell_rows``, ``cell_cols``: every above-threshold cell, ``cell_group`` its detection and
    ``cell_echo`` its connected echo (``0..n_echoes-1``).
    """

    rows: np.ndarray
    cols: np.ndarray
    amplitude: np.ndarray
    span_rows: np.ndarray
    span_cols: np.ndarray
    cell_rows: np.ndarray
    cell_cols: np.ndarray
    cell_group: np.ndarray
    cell_echo: np.ndarray
    n_echoes: int

    def __len__(self) -> int:
        return len(self.amplitude)


def label_cells(mask: np.ndarray, merge_bins: int, merge_beams: int) -> tuple[np.ndarray, int]:
    """Components of ``mask`` whose cells are at most ``merge_bins - 1`` rows and ``merge_beams - 1``
    columns apart (any sizes; see module docstring). Returns ``(labels, n)`` as ``ndimage.label``."""
    if merge_bins <= 1 and merge_beams <= 1:
        # No joining: every cell its own component.
        labels = np.zeros(mask.shape, np.int32)
        n = int(np.count_nonzero(mask))
        labels[mask] = np.arange(1, n + 1, dtype=np.int32)
        return labels, n
    grown = mask
    kb, kw = max(merge_bins - 1, 1), max(merge_beams - 1, 1)
    if kb > 1 or kw > 1:
        # Widen each cell to a kb x kw box (where the box sits around the cell does not matter, it
        # is the same for every cell; clipping at the border never cuts the sides that touch).
        grown = ndimage.maximum_filter(mask, size=(kb, kw), mode='constant', cval=False)
    structure = np.zeros((3, 3), bool)
    structure[1, 1] = True
    if merge_bins > 1:
        structure[:, 1] = True
    if merge_beams > 1:
        structure[1, :] = True
    if merge_bins > 1 and merge_beams > 1:
        structure[:] = True
    labels, n = ndimage.label(grown, structure=structure)
    if grown is not mask:
        labels[~mask] = 0
    return labels, int(n)


def threshold_cells(amplitudes: np.ndarray, tau: float, merge_bins: int = 1, merge_beams: int = 1,
                    connected: bool = False, echoes: bool = True) -> CellDetections:
    """Cells with amplitude ``> tau`` (ESC eq. 16's event), grouped as the module docstring says.

    ``connected`` selects the ``connected`` grouping; ``echoes = False`` skips labelling the
    connected echoes where nobody needs them (``cell_echo`` is then all 0, ``n_echoes`` 0).
    Callers validate amplitudes first (finite).
    """
    a = np.asarray(amplitudes)
    above = a > tau
    rows, cols = np.nonzero(above)
    amp = a[rows, cols]
    if echoes or connected:
        echo_labels, n_echo = label_cells(above, max(merge_bins, 2), max(merge_beams, 2))
        echo = echo_labels[rows, cols] - 1
        del echo_labels
    else:
        echo, n_echo = np.zeros(len(rows), np.int64), 0
    if connected:
        group, n = echo, n_echo
    elif merge_bins <= 1 and merge_beams <= 1:
        # The paper's cells: each cell is its own detection, exactly as found.
        ones = np.ones(len(rows), np.int64)
        return CellDetections(rows.astype(float), cols.astype(float), amp.astype(float), ones, ones,
                              rows, cols, np.arange(len(rows)), echo, n_echo)
    else:
        labels, n = label_cells(above, merge_bins, merge_beams)
        group = labels[rows, cols] - 1
    w = amp.astype(float)
    total = np.bincount(group, weights=w, minlength=n)
    r = np.bincount(group, weights=w * rows, minlength=n) / total
    c = np.bincount(group, weights=w * cols, minlength=n) / total
    peak = np.zeros(n)
    np.maximum.at(peak, group, w)
    span_r, span_c = _span(group, rows, n), _span(group, cols, n)
    return CellDetections(r, c, peak, span_r, span_c, rows, cols, group, echo, n_echo)


def _span(group: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    """Number of rows (or columns) each group spans: max - min + 1."""
    lo = np.full(n, np.iinfo(np.int64).max)
    hi = np.full(n, -1)
    np.minimum.at(lo, group, index)
    np.maximum.at(hi, group, index)
    return hi - lo + 1

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
exactly when their cells are at most ``m - 1`` apart in that direction. A frame with few cells above
the threshold (a CFAR frame of an imaging sonar: tens of its 512 000 cells) joins the cells
themselves instead, pairs at most that far apart, and numbers the components as the image labelling
does (by the first pixel of their boxes in row-major order): the same labels without passes over
the frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from sonar_tracking.core.jit import kernel

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


#: Frames with at most one above-threshold cell in this many are labelled from their cells.
_SPARSE = 256


def label_cells(mask: np.ndarray, merge_bins: int, merge_beams: int) -> tuple[np.ndarray, int]:
    """Components of ``mask`` whose cells are at most ``merge_bins - 1`` rows and ``merge_beams - 1``
    columns apart (any sizes; see module docstring). Returns ``(labels, n)`` as ``ndimage.label``."""
    if merge_bins <= 1 and merge_beams <= 1:
        # No joining: every cell its own component.
        labels = np.zeros(mask.shape, np.int32)
        n = int(np.count_nonzero(mask))
        labels[mask] = np.arange(1, n + 1, dtype=np.int32)
        return labels, n
    labels, n = _label_grown(mask, merge_bins, merge_beams)
    if labels.size and n:
        labels[~mask] = 0
    return labels, n


def _boxes(merge_bins: int, merge_beams: int) -> tuple[int, int]:
    """The box each cell is widened to, rows x columns (module docstring)."""
    return max(merge_bins - 1, 1), max(merge_beams - 1, 1)


def _label_grown(mask: np.ndarray, merge_bins: int, merge_beams: int) -> tuple[np.ndarray, int]:
    """Labels of the widened cells' components (every pixel of the boxes labelled)."""
    grown = mask
    kb, kw = _boxes(merge_bins, merge_beams)
    if (kb > 1 or kw > 1) and mask.size:
        # Widen each cell to a kb x kw box (where the box sits around the cell does not matter, it
        # is the same for every cell; clipping at the border never cuts the sides that touch). A
        # cell's box spans -((k - 1) // 2) .. k // 2 around it, where ndimage.maximum_filter puts it;
        # dilating the bytes with the kernel's centre at k // 2 is the same maximum, faster.
        cells = np.ascontiguousarray(mask, dtype=np.bool_).view(np.uint8)
        grown = cv2.dilate(cells, np.ones((kb, kw), np.uint8), borderType=cv2.BORDER_CONSTANT,
                           borderValue=0).view(np.bool_)
    structure = np.zeros((3, 3), bool)
    structure[1, 1] = True
    if merge_bins > 1:
        structure[:, 1] = True
    if merge_beams > 1:
        structure[1, :] = True
    if merge_bins > 1 and merge_beams > 1:
        structure[:] = True
    labels, n = ndimage.label(grown, structure=structure)
    return labels, int(n)


def _labels_at(mask: np.ndarray, rows: np.ndarray, cols: np.ndarray, merge_bins: int,
               merge_beams: int) -> tuple[np.ndarray, int]:
    """``label_cells(mask, merge_bins, merge_beams)`` at the cells ``rows, cols`` (all of ``mask``'s
    cells in row-major order), 1-based, and the number of components."""
    if merge_bins <= 1 and merge_beams <= 1:
        return np.arange(1, len(rows) + 1, dtype=np.int32), len(rows)
    if len(rows) * _SPARSE > mask.size:
        labels, n = _label_grown(mask, merge_bins, merge_beams)
        return labels[rows, cols], n
    kb, kw = _boxes(merge_bins, merge_beams)
    labels = np.empty(len(rows), np.int32)
    n = _join_cells(rows, cols, mask.shape[1], kb if merge_bins > 1 else 0, kw if merge_beams > 1 else 0,
                    (kb - 1) // 2, (kw - 1) // 2, labels)
    return labels, int(n)


@kernel
def _join_cells(rows, cols, width, reach_rows, reach_cols, lead_rows, lead_cols, labels):
    """Components of the cells ``rows, cols`` (row-major order) joined where they are at most
    ``reach_rows`` rows and ``reach_cols`` columns apart, numbered 1.. by the row-major order of their
    boxes' first pixel (a box starts ``lead_rows``, ``lead_cols`` before its cell, clipped at 0), as
    ``ndimage.label`` numbers the widened image; into ``labels``. Returns the number of components."""
    m = rows.shape[0]
    parent = np.arange(m)
    if m == 0:
        return 0
    last_row = rows[m - 1]
    start = np.zeros(last_row + 2, np.int64)     # start[r]: first cell of row r or later
    k = 0
    for r in range(last_row + 2):
        while k < m and rows[k] < r:
            k += 1
        start[r] = k
    for i in range(m):
        r, c = rows[i], cols[i]
        for rr in range(r, min(r + reach_rows, last_row) + 1):
            lo, hi = start[rr], start[rr + 1]
            if rr == r:
                lo = i + 1
            lo += np.searchsorted(cols[lo:hi], c - reach_cols)
            for j in range(lo, hi):
                if cols[j] > c + reach_cols:
                    break
                a, b = i, j
                while parent[a] != a:
                    parent[a] = parent[parent[a]]
                    a = parent[a]
                while parent[b] != b:
                    parent[b] = parent[parent[b]]
                    b = parent[b]
                if a != b:
                    parent[max(a, b)] = min(a, b)
    first = np.full(m, np.iinfo(np.int64).max)
    for i in range(m):
        a = i
        while parent[a] != a:
            a = parent[a]
        parent[i] = a
        key = max(rows[i] - lead_rows, 0) * width + max(cols[i] - lead_cols, 0)
        if key < first[a]:
            first[a] = key
    roots = np.flatnonzero(parent == np.arange(m))
    order = roots[np.argsort(first[roots])]
    number = np.zeros(m, np.int32)
    for k in range(order.shape[0]):
        number[order[k]] = k + 1
    for i in range(m):
        labels[i] = number[parent[i]]
    return order.shape[0]


def threshold_cells(amplitudes: np.ndarray, tau: float, merge_bins: int = 1, merge_beams: int = 1,
                    connected: bool = False, echoes: bool = True) -> CellDetections:
    """Cells with amplitude ``> tau`` (ESC eq. 16's event), grouped as the module docstring says.

    ``connected`` selects the ``connected`` grouping; ``echoes = False`` skips labelling the
    connected echoes where nobody needs them (``cell_echo`` is then all 0, ``n_echoes`` 0).
    Callers validate amplitudes first (finite).
    """
    a = np.asarray(amplitudes)
    above = a > tau
    # np.nonzero's row-major cells; through the flat indices, several times faster on a whole frame
    rows, cols = np.divmod(np.flatnonzero(above), max(above.shape[1], 1)) if above.ndim == 2 else np.nonzero(above)
    amp = a[rows, cols]
    if echoes or connected:
        echo_labels, n_echo = _labels_at(above, rows, cols, max(merge_bins, 2), max(merge_beams, 2))
        echo = echo_labels - 1
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
        labels, n = _labels_at(above, rows, cols, merge_bins, merge_beams)
        group = labels - 1
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

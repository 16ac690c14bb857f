"""Region-growing segmentation of the processed FLS image (FLS paper §1, §2), and its plain baseline.

The paper grows regions from seeds with a "modified" region growing it does not describe. Our
design works on the filtered, range-normalised image of :mod:`.filters` (1 = local background
level), each choice with its reason:

1. **Seeds and growth by two thresholds in dB above the local background** (``seed_db``,
   ``grow_db``). A region starts only where the echo is clearly above the background (few false
   seeds) and grows over the connected pixels that are still above a lower level, so a target's
   weaker skirts (beam pattern, pulse) join its region instead of being cut off or becoming
   regions of their own. Because the image is normalised per range, the same thresholds hold at
   every range (a constant false-alarm rate), although echoes fall with range.
2. **Growth tolerance** (``tolerance_db``): a grown pixel must be within this many dB of its
   region's peak. This is the homogeneity criterion of classical region growing, stated for
   multiplicative speckle as a ratio: it keeps a strong target's region to its main lobe rather
   than its whole, wide, beam-pattern skirt.
3. **Fragments joined** (``join_distance``): regions whose pixels come within this distance of
   each other are one region (single-linkage; implemented as connected components of the mask
   dilated by half the distance, each pixel keeping the component of its dilation). Different
   faces and corners of one target, and its surface-multipath echo just behind it, often appear
   as unconnected regions (paper §2, drawbacks 2 and 3); two tank targets are metres apart.
4. **Area in resolution cells** (``min_cells``): a region's size is counted in sonar resolution
   cells (pixel area divided by the cell area ``r * beam step * range step`` at the pixel's range),
   because speckle and small echoes come in cells: a one-cell false alarm covers a few pixels far
   out and a fraction of one near the sonar, so a pixel count would either keep far false alarms
   or drop near targets. ``max_area`` (m^2) drops extended returns (walls, seabed).

The plain baseline, :func:`threshold_components`, is one global threshold and the 8-connected
components of what is above it, with a minimum pixel count.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.fls.grid import ImageGrid

__all__ = ['SegmentConfig', 'grow_regions', 'threshold_components', 'cells_per_pixel', 'relabel']


@dataclass(frozen=True)
class SegmentConfig(Config):
    """Settings of the modified region growing."""

    seed_db: float = setting(5.5, 'a region starts where the filtered image is this far above the background',
                             unit='dB', low=-20.0, high=60.0)
    grow_db: float = setting(3.0, 'regions grow over connected pixels this far above the background',
                             unit='dB', low=-20.0, high=60.0)
    tolerance_db: float = setting(20.0, 'growth tolerance: grown pixels are within this of the region peak',
                                  unit='dB', low=0.0, high=120.0)
    join_distance: float = setting(0.5, 'regions closer than this are fragments of one target (0 = never join)',
                                   unit='m', low=0.0, high=20.0)
    min_cells: float = setting(6.0, 'smallest region, in sonar resolution cells', low=0.0, high=1e6)
    max_area: float = setting(50.0, 'largest region', unit='m^2', low=0.0, low_open=True, high=1e6)
    max_regions: int = setting(200, 'at most this many regions per image (the strongest are kept)',
                               low=1, high=100000)

    def validate(self) -> None:
        if self.grow_db > self.seed_db:
            raise ConfigError(f'grow_db = {self.grow_db} must not exceed seed_db = {self.seed_db} '
                              '(regions grow from seeds to weaker pixels)')


def cells_per_pixel(grid: ImageGrid, sensor_pose: tuple[float, float, float], angle_increment: float,
                    range_resolution: float) -> np.ndarray:
    """Resolution cells per pixel: pixel area over ``r * angle_increment * range_resolution`` at each
    pixel's range ``r`` from the sensor (float32, shape of the grid)."""
    x, y = grid.pixel_centres()
    r = np.hypot(x - sensor_pose[0], y - sensor_pose[1])
    dr = max(range_resolution, 1e-6)
    cell = np.maximum(r, 0.5 * grid.resolution) * max(angle_increment, 1e-9) * dr
    return (grid.resolution ** 2 / cell).astype(np.float32)


def relabel(labels: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, int]:
    """Labels renumbered ``1..n`` over the labels where ``keep[label]`` (others become 0)."""
    keep = keep.copy()
    keep[0] = False
    remap = np.zeros(keep.size, np.int32)
    n = int(keep.sum())
    remap[keep] = np.arange(1, n + 1, dtype=np.int32)
    return remap[labels], n


def _label_max(values: np.ndarray, labels: np.ndarray, n: int) -> np.ndarray:
    """Largest value per label ``0..n-1`` (0 where a label has none) of a few labelled pixels."""
    out = np.zeros(n, np.float32)
    np.maximum.at(out, labels, values)
    return out


def grow_regions(image: np.ndarray, config: SegmentConfig, resolution: float,
                 cell_weight: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Segment a range-normalised image (1 = background) into regions (see module docstring).

    ``cell_weight`` gives resolution cells per pixel (:func:`cells_per_pixel`); without it a pixel
    counts as one cell. Returns ``(labels, n)``: int32 labels, 0 = background, regions ``1..n``
    numbered in raster order of their first pixel.
    """
    c = config
    img = np.nan_to_num(np.asarray(image, dtype=np.float32), nan=0.0)
    grow = (img > 10.0 ** (c.grow_db / 10.0)).astype(np.uint8)
    n, lab = cv2.connectedComponents(grow, connectivity=8, ltype=cv2.CV_32S)
    if n <= 1:
        return np.zeros(img.shape, np.int32), 0
    seeded = np.zeros(n, bool)
    seeded[lab[img > 10.0 ** (c.seed_db / 10.0)]] = True
    seeded[0] = False
    grown = lab > 0
    peak = _label_max(img[grown], lab[grown], n)
    mask = seeded[lab] & (img >= peak[lab] * np.float32(10.0 ** (-c.tolerance_db / 10.0)))
    radius = c.join_distance / (2.0 * resolution)
    if radius >= 0.5:
        k = int(round(radius))
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
        joined = cv2.dilate(mask.astype(np.uint8), kernel)
        n, lab = cv2.connectedComponents(joined, connectivity=8, ltype=cv2.CV_32S)
    else:
        n, lab = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    lab = np.where(mask, lab, 0)
    on = lab[mask]
    weights = cell_weight[mask] if cell_weight is not None else None
    cells = np.bincount(on, weights=weights, minlength=n)
    area = np.bincount(on, minlength=n) * resolution ** 2
    keep = (cells >= c.min_cells) & (area <= c.max_area)
    keep[0] = False
    if keep.sum() > c.max_regions:
        strength = _label_max(img[mask], on, n)
        order = np.argsort(-np.where(keep, strength, -np.inf), kind='stable')
        keep[:] = False
        keep[order[:c.max_regions]] = True
    return relabel(lab, keep)


def threshold_components(image: np.ndarray, threshold: float, min_pixels: int = 1) -> tuple[np.ndarray, int]:
    """Plain segmentation (the baseline): pixels above ``threshold``, 8-connected components of at
    least ``min_pixels`` pixels. Returns ``(labels, n)`` as :func:`grow_regions`."""
    img = np.nan_to_num(np.asarray(image, dtype=np.float32), nan=0.0)
    n, lab = cv2.connectedComponents((img > threshold).astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    area = np.bincount(lab.ravel(), minlength=n)
    return relabel(lab, area >= max(1, int(min_pixels)))

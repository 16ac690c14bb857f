"""Feature cues: each particle's features from the processed image, and their distance to a template.

**Where a particle's features come from.** Eq. (13) compares "each particle feature" with the
track's template, so a particle at ``(x, y)`` must have a value of every selected Table 2 feature.
We take the *window region* at the particle (:mod:`sonar_tracking.core.fls.windows`): the square
of ``n x n`` pixels of ``/fls/image`` centred on the pixel that contains ``(x, y)`` (``n`` the odd
number of pixels closest to ``cues.window``, 0.7 m: the bright core of a tank target's echo), every pixel of the
square counted as region, with the one-pixel ring around it as the region's surrounding; the
features are exactly those of Table 2 (``core.fls.features``) on those pixels. Why:

* the template is measured the same way at the region where the track starts, so a particle on
  the target compares like with like; a segmented region's own features (``/fls/regions``)
  depend on where segmentation drew its border, which a particle does not have;
* a particle away from the target still gets well-defined features (background), so every
  particle has a likelihood and the likelihood falls smoothly as the window slides off the
  target; a thresholded region would be empty there;
* the features of a full square can be computed for 300 particles in about a millisecond.

The window's mean intensity (f03) is highest on the target, its ring's mean (f06) lowest when the
target sits inside the window, the moment invariants (f17, f20) of the intensity in the window
grow when the target is off-centre, and the texture (f24) changes where target pixels are.

**Distances.** Features of different kinds live on different scales, so each is compared after a
transform that makes its variation roughly even, divided by a scale ``sigma_i``: ``d_i =
(T_i(S) - T_i(S_m)) / sigma_i``, i.e. ``beta_i = 1 / sigma_i^2`` in eq. (13). Intensities (f03,
f04, f06, f08) in dB; signed small-magnitude features (f07 and Hu's invariants f14-f20, whose
magnitudes span decades and change sign) through ``asinh(v / ref_i)``, linear near zero and
logarithmic beyond ``ref_i``; the bounded co-occurrence statistics and f09 as they are.
``sigma_i`` is the root-mean-square change of the transformed feature of a target's window
between consecutive frames, measured with the default window (7 pixels of 0.1 m) on simulated
FLS Table 5 situations 1-4 and 8-11 (four seeds each, SeaKing 675 kHz, default ``fls_features``
settings; :func:`sonar_tracking.studies.fls_study.cue_statistics`): the likelihood then says
how far a particle's window is from the template in units of the target's own frame-to-frame
variation. ``ref_i`` is the median magnitude of the feature on targets in the same data.

**Thresholds.** Eq. (18) calls cue i degenerated when its reliability falls below ``T_i``
(:mod:`.fusion`: ``Delta_0 / Delta_i``, how many times the cue concentrates the particles). The
cues differ: on a healthy track the window mean (f03) concentrates the particles a little (its
lower quartile is 1.15), the moment invariants (f17, f20) hardly at all (they vary as much off the
target as on it). So ``T_i`` is per cue: the 7.5th percentile of its reliability on healthy tracks
(particles 0.4 m around the imaged centre, template from the previous frame, frames where
segmentation finds the target, ``alpha = 1``; 432 samples of situations 1-4 and 8-11, four runs
each, seed 7; :func:`sonar_tracking.studies.fls_study.reliability_statistics` with ``quantile
7.5``): a cue is degenerated when it does worse than in 92.5 % of healthy frames. With the paper's
five cues all five are above their thresholds together in 77 % of healthy frames, which is
§4.2.2's "as a feature clue is good, MF ... otherwise, WF": adaptive fusion is MF on a healthy
track and WF when a cue fails (and, with the ``crossing`` switch, near another track).
``fusion.thresholds`` may set them explicitly.

Why the 7.5th percentile and not the lower quartile: ``docs/experiments/2026-11-21-fls-gpf-study.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.fls.features import FEATURE_LABELS, FeatureConfig
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.fls.windows import WindowImage

__all__ = ['CueSpec', 'CUE_SPECS', 'CueModel', 'window_pixels', 'pixel_index', 'coarsening', 'coarsen', 'MAX_WINDOW']

#: Largest window side in pixels (a coarse image gets at least 3, a fine one at most this: the work
#: per particle grows with the window's area).
MAX_WINDOW = 41


@dataclass(frozen=True)
class CueSpec:
    """How feature ``number`` is compared: transform (``db``, ``asinh``, ``linear``), the scale
    ``sigma`` of the transformed value, its reference magnitude (``asinh`` only) and the cue's
    calibrated threshold ``T_i`` of eq. (18) (see module docstring)."""

    number: int
    transform: str
    sigma: float
    ref: float = 1.0
    threshold: float = 1.0

    def apply(self, values: np.ndarray) -> np.ndarray:
        """The transformed feature values."""
        if self.transform == 'db':
            return 10.0 * np.log10(np.maximum(values, 1e-6))
        if self.transform == 'asinh':
            return np.arcsinh(values / self.ref)
        return np.asarray(values, dtype=np.float64)


def _specs() -> dict[int, CueSpec]:
    # feature: (transform, sigma, ref, T_i) from the calibrations described in the module docstring.
    table = {
        3: ('db', 2.6, 1.0, 0.98), 4: ('db', 4.8, 1.0, 0.99), 6: ('db', 1.5, 1.0, 0.82),
        7: ('asinh', 0.84, 0.92, 0.89), 8: ('db', 1.9, 1.0, 0.91), 9: ('linear', 0.19, 1.0, 0.91),
        14: ('asinh', 0.51, 0.054, 1.00), 15: ('asinh', 0.75, 7.7e-5, 0.94), 16: ('asinh', 1.3, 3.6e-6, 0.93),
        17: ('asinh', 1.3, 4.8e-6, 0.86), 18: ('asinh', 3.1, 1.3e-11, 0.92), 19: ('asinh', 2.3, 2.3e-8, 0.88),
        20: ('asinh', 4.0, 7.6e-12, 0.92), 21: ('linear', 0.9, 1.0, 0.91), 22: ('linear', 0.75, 1.0, 1.06),
        23: ('linear', 0.26, 1.0, 1.29), 24: ('linear', 0.11, 1.0, 0.98), 25: ('linear', 0.28, 1.0, 1.03),
        26: ('linear', 0.98, 1.0, 0.91), 27: ('linear', 0.96, 1.0, 0.96), 28: ('linear', 0.57, 1.0, 1.12),
        29: ('linear', 3.1, 1.0, 0.91), 30: ('linear', 0.36, 1.0, 1.03),
    }
    return {n: CueSpec(n, *v) for n, v in table.items()}


#: Transform and scale of every Table 2 feature usable as a cue (not the window's own shape: f01,
#: f02, f05, f10-f13 are the same for every window).
CUE_SPECS: dict[int, CueSpec] = _specs()


def window_pixels(window: float, resolution: float, largest: int | None = MAX_WINDOW) -> int:
    """The odd number of pixels closest to ``window`` metres, at least 3 and at most ``largest``
    (None: no limit)."""
    ratio = round(window / resolution, 9)  # 0.7 / 0.05 is 13.999999999999998
    n = int(round(ratio))
    if n % 2 == 0:
        n = n + 1 if ratio >= n else n - 1
    n = max(n, 3)
    return int(n if largest is None else min(n, largest))


def coarsening(pixel: float, resolution: float) -> int:
    """The block size (pixels per side) that averages an image of ``resolution`` to the coarsest
    pixel not larger than ``pixel`` metres (1: the image as it is; ``pixel`` 0: always 1)."""
    if pixel <= 0.0:
        return 1
    return max(1, int(math.floor(pixel / resolution + 1e-9)))


def coarsen(image: np.ndarray, valid: np.ndarray, grid: ImageGrid, factor: int) -> tuple[np.ndarray, ImageGrid]:
    """The image averaged over blocks of ``factor x factor`` pixels, each block the mean of its
    ``valid`` pixels (0 = no data where none is), and the grid of the blocks (same origin)."""
    h, w = image.shape
    rows, cols = np.arange(0, h, factor), np.arange(0, w, factor)     # block starts; the last may be partial
    sums = np.add.reduceat(np.add.reduceat(np.where(valid, image, 0.0), cols, axis=1), rows, axis=0)
    counts = np.add.reduceat(np.add.reduceat(valid.astype(np.float64), cols, axis=1), rows, axis=0)
    out = np.divide(sums, counts, out=np.zeros_like(sums), where=counts > 0)
    hc, wc = out.shape
    coarse = ImageGrid(resolution=grid.resolution * factor, width=wc, height=hc, origin_x=grid.origin_x,
                       origin_y=grid.origin_y, origin_yaw=grid.origin_yaw)
    return out, coarse


def pixel_index(fractional: np.ndarray) -> np.ndarray:
    """Integer pixel indices of fractional positions (:meth:`~..fls.grid.ImageGrid.point_to_pixel`),
    non-finite and huge values pushed far outside the image (where windows hold no data)."""
    return np.rint(np.nan_to_num(fractional, nan=-1e9, posinf=1e9, neginf=-1e9)).clip(-1e9, 1e9).astype(np.int64)


class CueModel:
    """The selected features as cues: per-particle values, distances to a template (eq. 13)."""

    def __init__(self, features: tuple[int, ...], window: float, alpha: float = 1.0,
                 feature_config: FeatureConfig | None = None) -> None:
        missing = [f for f in features if f not in CUE_SPECS]
        if missing:
            raise ValueError(f'features {missing} cannot be cues ({", ".join(FEATURE_LABELS[f - 1] for f in missing)} '
                             'are the same for every window); choose from '
                             f'{sorted(CUE_SPECS)}')
        self.features = tuple(int(f) for f in features)
        self.specs = [CUE_SPECS[f] for f in self.features]
        self.sigma = np.array([s.sigma for s in self.specs])
        self.window = float(window)
        self.alpha = float(alpha)
        self.feature_config = feature_config or FeatureConfig()

    @property
    def m(self) -> int:
        """Number of cues."""
        return len(self.features)

    def prepare(self, image: np.ndarray) -> WindowImage:
        """The frame's image, ready for many window lookups."""
        return WindowImage(image, self.feature_config, MAX_WINDOW)

    def values(self, wi: WindowImage, grid: ImageGrid, xy: np.ndarray, size: int | None = None,
               clouds: np.ndarray | None = None) -> np.ndarray:
        """Transformed features ``(m, K)`` of the windows at positions ``xy (K, 2)`` (image frame),
        ``size`` pixels wide (default :func:`window_pixels` of the grid); ``clouds (K,)`` says which
        particle cloud each position belongs to when several are looked up together (the results
        are those of looking up each cloud alone). Particles of a cloud in one pixel share its
        window, so each distinct window is computed once."""
        if size is None:
            size = window_pixels(self.window, grid.resolution)
        r, c = grid.point_to_pixel(xy[:, 0], xy[:, 1])
        rows, cols = pixel_index(r), pixel_index(c)
        if len(rows) > 1:
            # Windows far outside all hold no data: clipped, they keep one key per cloud and side.
            h, w = grid.shape
            reach = size // 2 + 2
            span = (h + 2 * reach + 1) * (w + 2 * reach + 1)
            key = ((np.clip(rows, -reach, h + reach) + reach) * (w + 2 * reach + 1) +
                   np.clip(cols, -reach, w + reach) + reach)
            if clouds is not None:
                key = key + np.asarray(clouds, dtype=np.int64) * span
            _, first, inverse, counts = np.unique(key, return_index=True, return_inverse=True, return_counts=True)
            groups = None if clouds is None else np.asarray(clouds)[first]
            raw = wi.features(rows[first], cols[first], size, self.features, groups, counts)[inverse.reshape(-1)]
        else:
            raw = wi.features(rows, cols, size, self.features)
        out = np.empty((self.m, len(xy)))
        for i, spec in enumerate(self.specs):
            out[i] = spec.apply(raw[:, i])
        return out

    def distances2(self, values: np.ndarray, template: np.ndarray) -> np.ndarray:
        """``beta_i d^2(S^i, S_m^i)`` of eq. (13): squared scaled distances ``(m, K)`` of values
        ``(m, K)`` to a template ``(m,)``, or ``(n, m, K)`` of n tracks' values to their templates
        ``(n, m)``."""
        d = (values - template[..., None]) / self.sigma[:, None]
        return d * d

    def log_likelihoods(self, d2: np.ndarray) -> np.ndarray:
        """``ln P_S(y^i | x)`` of eq. (13) per cue and particle, ``(m, K)``:
        ``-ln sqrt(2 pi alpha) - beta_i d^2 / (2 alpha^2)`` (the normaliser as printed)."""
        return -0.5 * math.log(2.0 * math.pi * self.alpha) - d2 / (2.0 * self.alpha ** 2)

    def background(self, wi: WindowImage, grid: ImageGrid, valid: np.ndarray, count: int = 400) -> np.ndarray:
        """Transformed features ``(m,)`` of the frame's background: the median over windows centred on
        the pixels with data of a regular lattice of about ``count`` pixels (targets are few, so the
        median is background); NaN when the image holds no data."""
        h, w = valid.shape
        step = max(1, int(math.ceil(math.sqrt(h * w / count))))
        rows, cols = np.meshgrid(np.arange(step // 2, h, step), np.arange(step // 2, w, step), indexing='ij')
        keep = valid[rows, cols]
        if not keep.any():
            return np.full(self.m, np.nan)
        raw = wi.features(rows[keep], cols[keep], window_pixels(self.window, grid.resolution), self.features)
        return np.array([spec.apply(np.median(raw[:, i])) for i, spec in enumerate(self.specs)])

    @staticmethod
    def match(d2: np.ndarray) -> np.ndarray:
        """Mean over cues of the squared scaled distance: 1 on average for the target itself."""
        return d2.mean(axis=0)

"""Multi-target management around the per-track filters (§4.2.3 steps 1 and 3, and ours).

* **Births (step 1).** The paper selects "interesting targets in the first image frame"; a
  running tracker must find them in every frame, so a track starts on every region of
  ``/fls/regions`` that no track explains. A track explains the region nearest to it (squared
  Mahalanobis distance with its position covariance plus the initial spread, below
  ``birth.gate``) and any region within ``birth.separation`` of its estimate (fragments and
  multipath ghosts of its target); other regions, even close by, are other targets (side-by-side
  targets of Table 5 situations 5-7 and 12 are 2.5-3 m apart).
* **Initial spread.** Step 1 draws the first particles from ``N(x; x_target, 45)`` and
  ``N(y; y_target, 40)``: variances in the paper's image pixels, x across its image and y along
  range. The paper does not say how large its pixels were; we read them at 0.1 m, the default
  resolution of our FLS image (close to the SeaKing 675 kHz's cross-range resolution at 4 m and
  twice its range bin), which gives 0.67 m across and 0.63 m along the line of sight: about the
  size of the tank targets, which is what the spread must cover. The values are metres in the
  settings (``birth.sigma_cross``, ``birth.sigma_range``), so they do not change when the image
  resolution does, and they are turned to the line of sight from the sonar when its position is
  known (world x/y otherwise). Velocity starts at zero with ``birth.sigma_speed`` per axis.
* **Lost (step 3).** A frame whose update does not find the target (see :mod:`.tracker`) leaves
  the prediction in place and multiplies the covariance by ``lost.inflation`` (up to
  ``lost.max_std``), so the next frame's particles search wider. The prediction between frames
  still adds the velocity's uncertainty, so a young lost track's search keeps growing. That growth
  is not capped at ``max_std``: the wide search is what lets re-finding carry tracks through
  crossings (measurements: ``docs/experiments/2026-11-27-notes-from-code.md``). A lost track
  that has a region no other track explains within ``lost.refind_gate`` (its widened covariance
  plus the initial spread) takes it up again: a Kalman update of the track by the region's position
  (noise ``lost.refind_sigma``), which keeps its id and template and corrects its velocity. Confirmed
  tracks choose first; when several lost tracks and regions compete (two targets passing each
  other), the pairs of least total squared Mahalanobis distance are taken. The cost leaves the
  templates out: the templates of weak echoes are too alike to tell targets apart (same notes). A
  confirmed track ends after ``lost.max_time`` without its target, a tentative one after
  ``lost.tentative_time``.
  One empty frame therefore never ends a confirmed track.
* **Leaving coverage (ours).** A track whose estimate has no pixel with data in its window (outside
  the sonar's fan, where ``/fls/image`` is 0, or outside the image) cannot see its target, and a
  target that left the fan will not come back where the track coasts. Such a track ends once its
  estimate has been outside for ``lost.outside_time``, however long ``lost.max_time`` is; a frame
  whose image holds no data at all (a dropout) neither starts nor stops that clock.
* **Template (ours).** The template follows the target's changing aspect by exponential
  forgetting, ``S_m <- (1 - rate) S_m + rate S(estimate)``, but only when the estimate matches the
  template well (``template.match``) and no other track's estimate is within ``template.guard``
  metres: while two targets cross, their windows hold both, and blending templates is how a
  tracker swaps or loses identities (Table 5 situations 8-11). The template is then frozen until
  they separate.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment

from sonar_tracking.core.gpf.config import BirthConfig, LostConfig, TemplateConfig

__all__ = ['birth_covariance', 'explains', 'unexplained', 'mahalanobis2', 'gated_assignment', 'reseed_pairs',
           'spaced', 'widen', 'template_may_update', 'blend_template', 'should_end', 'left_coverage']


def birth_covariance(xy: np.ndarray, config: BirthConfig, sensor_xy: tuple[float, float] | None = None
                     ) -> np.ndarray:
    """Initial covariances ``(N, 4, 4)`` of tracks born at positions ``xy (N, 2)``."""
    n = len(xy)
    if sensor_xy is None:
        c = np.ones(n)
        s = np.zeros(n)
    else:
        d = xy - np.asarray(sensor_xy, dtype=float)[None, :]
        r = np.hypot(d[:, 0], d[:, 1])
        ok = r > 1e-9
        c = np.where(ok, d[:, 0] / np.where(ok, r, 1.0), 1.0)
        s = np.where(ok, d[:, 1] / np.where(ok, r, 1.0), 0.0)
    vr, vc = config.sigma_range ** 2, config.sigma_cross ** 2
    cov = np.zeros((n, 4, 4))
    cov[:, 0, 0] = vr * c * c + vc * s * s
    cov[:, 1, 1] = vr * s * s + vc * c * c
    cov[:, 0, 1] = cov[:, 1, 0] = (vr - vc) * c * s
    cov[:, 2, 2] = cov[:, 3, 3] = config.sigma_speed ** 2
    return cov


def mahalanobis2(regions_xy: np.ndarray, means: np.ndarray, position_covs: np.ndarray,
                 birth_covs: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis distances ``(T, N)`` between T track positions and N regions, with the
    track's position covariance plus the region's initial position covariance."""
    d = regions_xy[None, :, :] - means[:, None, :]                       # (T, N, 2)
    S = position_covs[:, None] + birth_covs[None, :, :2, :2]             # (T, N, 2, 2)
    a, b, c = S[..., 0, 0], S[..., 0, 1], S[..., 1, 1]
    det = a * c - b * b
    return (c * d[..., 0] ** 2 - 2 * b * d[..., 0] * d[..., 1] + a * d[..., 1] ** 2) / det


def gated_assignment(cost: np.ndarray, gate: float) -> list[tuple[int, int]]:
    """Pairs ``(row, column)`` of least total cost among the entries below ``gate``, where leaving a
    row unpaired costs ``gate``: a pair is only made when it is cheaper than no pair, so a far pair
    is never forced to free a near one for another row (the trap of padding with large costs)."""
    n, m = cost.shape
    if n == 0 or m == 0:
        return []
    big = 1e18
    full = np.full((n, m + n), big)
    full[:, :m] = np.where(cost < gate, cost, big)
    full[np.arange(n), m + np.arange(n)] = gate
    rows, cols = linear_sum_assignment(full)
    return [(int(r), int(c)) for r, c in zip(rows, cols) if c < m and full[r, c] < big]


def reseed_pairs(regions_xy: np.ndarray, means: np.ndarray, position_covs: np.ndarray, birth_covs: np.ndarray,
                 gate: float) -> list[tuple[int, int]]:
    """Lost tracks and the free regions they find again: pairs ``(track, region)`` of least total
    squared Mahalanobis distance within ``gate`` (:func:`gated_assignment`)."""
    if len(regions_xy) == 0 or len(means) == 0:
        return []
    return gated_assignment(mahalanobis2(regions_xy, means, position_covs, birth_covs), gate)


def explains(regions_xy: np.ndarray, means: np.ndarray, position_covs: np.ndarray, config: BirthConfig,
             birth_covs: np.ndarray, separation: float) -> np.ndarray:
    """``(T, N)``: whether track ``t`` explains region ``n`` (see module docstring: its nearest region
    within the gate, and every region closer than ``separation``), given the tracks' positions
    ``(T, 2)``, position covariances ``(T, 2, 2)`` and the regions' initial covariances ``(N, 4, 4)``."""
    out = np.zeros((len(means), len(regions_xy)), bool)
    if out.size == 0:
        return out
    m2 = mahalanobis2(regions_xy, means, position_covs, birth_covs)
    d = regions_xy[None, :, :] - means[:, None, :]
    nearest = np.argmin(m2, axis=1)
    rows = np.arange(len(means))
    hit = m2[rows, nearest] < config.gate
    out[rows[hit], nearest[hit]] = True
    out |= np.hypot(d[..., 0], d[..., 1]) < separation
    return out


def unexplained(regions_xy: np.ndarray, means: np.ndarray, position_covs: np.ndarray, config: BirthConfig,
                birth_covs: np.ndarray, separation: float) -> np.ndarray:
    """Which regions ``(N, 2)`` no track explains (:func:`explains`)."""
    return ~np.any(explains(regions_xy, means, position_covs, config, birth_covs, separation), axis=0)


def spaced(points: np.ndarray, separation: float) -> np.ndarray:
    """Which of ``points (N, 2)`` to keep so that no two kept ones are closer than ``separation``,
    earlier points first: fragments of one target in one frame start one track, not several."""
    keep = np.zeros(len(points), bool)
    for i, p in enumerate(points):
        kept = points[keep]
        keep[i] = not len(kept) or bool(np.min(np.hypot(kept[:, 0] - p[0], kept[:, 1] - p[1])) >= separation)
    return keep


def widen(cov: np.ndarray, config: LostConfig) -> np.ndarray:
    """The covariance of a frame that did not see its target (step 3): scaled by ``inflation``,
    as far as a position std of ``max_std``."""
    biggest = float(np.max(np.linalg.eigvalsh(cov[:2, :2])))
    factor = config.inflation
    if biggest * factor > config.max_std ** 2:
        factor = max(1.0, config.max_std ** 2 / max(biggest, 1e-300))
    return cov * factor


def template_may_update(match: float, position: np.ndarray, others: np.ndarray, config: TemplateConfig) -> bool:
    """Whether a track whose estimate matched its template by ``match`` (mean scaled squared
    distance) may update it, other tracks' estimates being at ``others (T, 2)``."""
    if config.rate <= 0.0 or not match < config.match:
        return False
    return not (len(others) and np.min(np.hypot(others[:, 0] - position[0], others[:, 1] - position[1])) < config.guard)


def blend_template(template: np.ndarray, observed: np.ndarray, rate: float) -> np.ndarray:
    """``(1 - rate) template + rate observed`` (exponential forgetting of the appearance)."""
    return (1.0 - rate) * template + rate * observed


def should_end(confirmed: bool, last_seen: float, stamp: float, config: LostConfig) -> bool:
    """Whether a track not seen since ``last_seen`` ends at ``stamp``."""
    limit = config.max_time if confirmed else config.tentative_time
    return stamp - last_seen > limit + 1e-9 or not math.isfinite(stamp - last_seen)


def left_coverage(outside_since: float | None, stamp: float, config: LostConfig) -> bool:
    """Whether a track whose estimate has been outside the sonar's coverage since ``outside_since``
    (None: it is inside) ends at ``stamp``."""
    return outside_since is not None and stamp - outside_since >= config.outside_time - 1e-9

"""The multi-target GPF tracker: frames (processed image + regions) in, GPF_TRACK_DTYPE records out.

Per frame at time t (§4.2.3):

1. every track is predicted to t by its filter (:mod:`.filters`: the GPF's eqs. 9-12, or the SIR's
   particles moved by the motion model);
2. every track is updated on the image (step 2): particles drawn from its prediction, each
   particle's window features compared with the track's template per cue (eq. 13,
   :mod:`.cues`), the cues fused (:mod:`.fusion`: ``fusion.mode`` af, mf or wf; af is WF while
   another track's prediction is inside the track's cloud, ``fusion.switch``), the weights
   normalised and the posterior moments taken (:mod:`.gaussian`); when the estimate does not
   match the template the frame does not update the track and its covariance widens (step 3);
3. templates follow the targets' aspect where that is safe, tracks lost too long or outside the
   sonar's coverage too long end, regions no track explains start tentative tracks (step 1), and
   tracks confirmed by ``birth.confirm_hits`` independent detections are confirmed
   (:mod:`.management`): a frame counts when the track saw its target there *and* a region of that
   frame lies at it (the track explains it), the birth region included. A template match alone is
   no detection: it is the track's own template found again, so a track born from one speckle
   region that the next image still holds would otherwise confirm itself.

The updates of all tracks are done together: their particles' windows are looked up in one
batch (:meth:`.cues.CueModel.values`), as are the windows at their estimates, and the random
numbers are drawn in the same order as one track after the other would draw them, so a frame
gives the same tracks as updating each track on its own (to the last bit; with cues among f25-f29
to their round-off, :mod:`~..fls.windows`).

The image is checked (:func:`check_image`): negative pixels are refused, except round-off of the
image filters (down to ``NEGATIVE_TOLERANCE`` times the image's largest magnitude), which reads as
0. Window features are measured on the image block-averaged to the coarsest pixel not larger than
``cues.pixel`` (:func:`.cues.coarsen`; 0.1 m, the pixel the cue scales were calibrated on: a
0.1 m image is used as it is, a 0.025 m one in blocks of 4 x 4), so the window of ``cues.window``
metres keeps about the same number of pixels (:func:`.cues.window_pixels`) and the work per
particle stays bounded however fine the image; the window is capped at :data:`.cues.MAX_WINDOW`
pixels (with ``cues.pixel`` 0 on a very fine image; reported in :class:`StepReport`).

``method`` chooses the filter (:data:`.filters.FILTERS`): ``gpf``, or ``sir`` for the SIR particle
filter baseline with exactly the same cues, fusion, births and management, so the two differ only in
the filter; the EKF baseline (:class:`.ekf.EkfTracker`) is this tracker with the
:class:`.filters.Ekf` filter, which is updated on the regions instead of the image (no re-finding,
templates or coverage test). An image without any data
(all zero) updates nothing: tracks are predicted and count the frame as a miss. A stamp older
than the previous one raises :class:`~sonar_tracking.core.timeline.TimeWentBack` and changes
nothing; after :meth:`GpfTracker.reset` the tracker starts again (ids are never reused).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from sonar_tracking.core.fls.features import FeatureConfig
from sonar_tracking.core.fls.grid import ImageGrid
from sonar_tracking.core.fls.windows import WindowImage
from sonar_tracking.core.gpf.config import GpfConfig
from sonar_tracking.core.gpf.cues import MAX_WINDOW, CueModel, coarsen, coarsening, pixel_index, window_pixels
from sonar_tracking.core.gpf.filters import FILTERS, TrackFilter
from sonar_tracking.core.gpf.fusion import MF, WF, fuse_many, second_target
from sonar_tracking.core.gpf.gaussian import kalman_update
from sonar_tracking.core.gpf.management import (
    birth_covariance,
    blend_template,
    explains,
    left_coverage,
    reseed_pairs,
    should_end,
    spaced,
    template_may_update,
    unexplained,
    widen,
)
from sonar_tracking.core.gpf.track import GpfTrack, tracks_to_records
from sonar_tracking.core.records import GPF_TRACK_DTYPE
from sonar_tracking.core.timeline import check_forward

__all__ = ['GpfInputError', 'Frame', 'GpfTracker', 'StepReport', 'regions_xy', 'check_image', 'NEGATIVE_TOLERANCE']

METHODS = tuple(FILTERS)

#: Negative pixels down to this fraction of the image's largest magnitude are round-off of the image
#: filters (-1.5e-15 next to intensities near 1 on recorded frames; a 32FC1 image rounds at about
#: 1e-7 of its values) and read as 0; below it, refused.
NEGATIVE_TOLERANCE = 1e-6


class GpfInputError(ValueError):
    """A frame cannot be used; the message says what is wrong with it."""


@dataclass(frozen=True, eq=False)
class Frame:
    """A frame prepared for the tracks' updates: its grid, the image for window lookups and the
    background's transformed cue values (both None when the image holds no data)."""

    grid: ImageGrid
    windows: WindowImage | None
    background: np.ndarray | None
    window: int = 3

    @property
    def empty(self) -> bool:
        return self.windows is None


@dataclass
class StepReport:
    """What the last :meth:`GpfTracker.step` did."""

    stamp: float = math.nan
    tracks: int = 0
    confirmed: int = 0
    born: int = 0
    ended: int = 0
    seen: int = 0
    missed: int = 0
    mf: int = 0
    wf: int = 0
    regions: int = 0
    bad_regions: int = 0
    reseeded: int = 0
    outside: int = 0
    ended_outside: int = 0
    window_pixels: int = 0
    window_capped: bool = False
    cue_pixel: float = math.nan
    empty_image: bool = False
    seconds: dict[str, float] = field(default_factory=dict)

    def warnings(self) -> list[str]:
        """What about the frame deserves a warning (the frame was still used)."""
        out = []
        if self.window_capped:
            out.append(f'cues.window is more than {MAX_WINDOW} pixels of {self.cue_pixel:g} m: windows cut to '
                       f'{MAX_WINDOW}; set cues.pixel > 0')
        if self.bad_regions:
            out.append(f'{self.bad_regions} regions without a finite position ignored')
        return out

    def summary(self) -> dict[str, str]:
        """The frame's figures as text (a diagnostics report)."""
        return {'regions': str(self.regions), 'tracks': str(self.tracks), 'confirmed': str(self.confirmed),
                'born': str(self.born), 'ended': str(self.ended), 'seen': str(self.seen), 'missed': str(self.missed),
                'refound': str(self.reseeded), 'fusion_mf': str(self.mf), 'fusion_wf': str(self.wf),
                'empty_image': str(self.empty_image), 'outside': str(self.outside),
                'ended_outside': str(self.ended_outside), 'window_px': str(self.window_pixels),
                'cue_pixel_m': f'{self.cue_pixel:g}'} | {f'{k}_ms': f'{1e3 * v:.2f}' for k, v in self.seconds.items()}


def check_image(image: np.ndarray, grid: ImageGrid) -> np.ndarray:
    """The image as an array of numbers with the grid's shape, or GpfInputError saying what is wrong
    (non-finite pixels are left to :meth:`GpfTracker.prepare`, which reads them as no data).
    Negative pixels down to ``NEGATIVE_TOLERANCE`` times the largest finite magnitude are round-off
    and come back as 0 (in a copy); a more negative pixel is an error."""
    a = np.asarray(image)
    if a.ndim != 2:
        raise GpfInputError(f'image must be 2-D (rows x columns), got shape {a.shape}')
    if a.shape != grid.shape:
        raise GpfInputError(f'image is {a.shape[0]} x {a.shape[1]} pixels but its grid says {grid.height} x '
                            f'{grid.width}')
    if a.dtype.kind not in 'uif':
        raise GpfInputError(f'image has dtype {a.dtype}; expected numbers (processed intensity, 0 = no data)')
    if a.dtype.kind == 'u':
        return a
    negative = a < 0
    if negative.any():
        finite = np.isfinite(a)
        scale = float(np.max(np.abs(a[finite]))) if finite.any() else 0.0
        worst = float(a[negative].min())
        if worst < -NEGATIVE_TOLERANCE * scale:
            raise GpfInputError(f'image has {int(negative.sum())} negative pixels down to {worst:.3g} (largest '
                                f'magnitude {scale:.3g}); intensities are >= 0 (0 = no data), round-off of at most '
                                f'{NEGATIVE_TOLERANCE:g} of the largest magnitude is read as 0')
        a = np.where(negative, a.dtype.type(0), a)
    return a


def regions_xy(regions: np.ndarray | None) -> tuple[np.ndarray, int]:
    """Positions ``(N, 2)`` of REGION_DTYPE-like records with finite ``x, y``, and how many were not."""
    if regions is None or len(regions) == 0:
        return np.zeros((0, 2)), 0
    names = regions.dtype.names or ()
    if 'x' not in names or 'y' not in names:
        raise GpfInputError(f'regions need fields x and y; they have {sorted(names)}')
    xy = np.column_stack([regions['x'].astype(float), regions['y'].astype(float)]).reshape(-1, 2)
    ok = np.isfinite(xy).all(axis=1)
    return xy[ok], int((~ok).sum())


class GpfTracker:
    """GPF (or SIR) multi-target tracker on FLS frames; see the module docstring.

    ``rng`` is the only source of randomness; the same frames and seed give the same tracks.
    """

    def __init__(self, config: GpfConfig | None = None, rng: np.random.Generator | None = None,
                 method: str = 'gpf', feature_config: FeatureConfig | None = None,
                 track_filter: TrackFilter | None = None) -> None:
        if track_filter is None:
            if method not in METHODS:
                raise ValueError(f'method {method!r} must be one of {METHODS}')
            track_filter = FILTERS[method]()
        if rng is None and track_filter.weighs_image:
            raise ValueError('GpfTracker needs a numpy.random.Generator (rng=np.random.default_rng(seed))')
        self.method = track_filter.name
        self.filter = track_filter
        self.rng = rng
        self.feature_config = feature_config or FeatureConfig()
        self.configure(config or GpfConfig())
        self.tracks: list[GpfTrack] = []
        self.next_id = 1
        self.stamp: float | None = None
        self.report = StepReport()

    def configure(self, config: GpfConfig, feature_config: FeatureConfig | None = None) -> None:
        """Apply new settings; running tracks keep their state (templates are re-measured at their
        next update if the cue set changed)."""
        old = getattr(self, 'cues', None)
        self.config = config
        if feature_config is not None:
            self.feature_config = feature_config
        self.cues = CueModel(config.cues.numbers, config.cues.window, config.cues.alpha, self.feature_config)
        given = np.asarray(config.fusion.per_cue(self.cues.m), dtype=float)
        self.thresholds = np.where(given > 0, given, [spec.threshold for spec in self.cues.specs])
        self._cues_changed = old is not None and (old.features != self.cues.features or
                                                  old.feature_config != self.cues.feature_config or
                                                  old.window != self.cues.window)

    def reset(self) -> None:
        """End every track (ids keep counting)."""
        self.tracks = []
        self.stamp = None

    # -- the frame ------------------------------------------------------------------------------
    def step(self, stamp: float, image: np.ndarray, grid: ImageGrid, regions: np.ndarray | None = None,
             sensor_pose: tuple[float, float, float] | None = None) -> np.ndarray:
        """Process the frame at ``stamp`` [s]: ``image`` the processed image (``/fls/image``, 0 = no
        data) on ``grid``, ``regions`` its REGION_DTYPE records (only ``x, y`` are used), the sonar
        pose in the image frame if known. Returns the tracks as GPF_TRACK_DTYPE records."""
        return self._frame(stamp, check_image(image, grid), grid, regions, sensor_pose)

    def _frame(self, stamp: float, img: np.ndarray | None, grid: ImageGrid | None, regions: np.ndarray | None,
               sensor_pose: tuple[float, float, float] | None) -> np.ndarray:
        """One frame through the steps of the module docstring; ``img`` None for a filter that does
        not weigh the image (the EKF), whose update is on the regions."""
        t0 = time.perf_counter()
        if not math.isfinite(stamp):
            raise GpfInputError(f'frame stamp {stamp} is not finite')
        check_forward('frame', stamp, self.stamp)
        xy, bad = regions_xy(regions)
        rep = StepReport(stamp=float(stamp), regions=len(xy), bad_regions=bad)
        dt = 0.0 if self.stamp is None else float(stamp - self.stamp)
        self.stamp = float(stamp)
        if self._cues_changed:
            for tr in self.tracks:
                tr.template = None
            self._cues_changed = False

        self.filter.predict(self.tracks, dt, self.config.motion.noise, self.config.particles, self.rng)
        for tr in self.tracks:
            tr.stamp = float(stamp)
        t1 = time.perf_counter()
        sensor_xy = None if sensor_pose is None else (float(sensor_pose[0]), float(sensor_pose[1]))
        covs = birth_covariance(xy, self.config.birth, sensor_xy)
        used = np.zeros(len(xy), bool)
        frame = None
        if self.filter.weighs_image:
            if img is None or grid is None:
                raise GpfInputError(f'the {self.method} filter weighs the image: a frame needs its image and grid')
            frame = self._prepare(img, grid)
            rep.empty_image = frame.empty
            rep.window_pixels, rep.cue_pixel = frame.window, frame.grid.resolution
            rep.window_capped = frame.window == MAX_WINDOW and window_pixels(self.config.cues.window,
                                                                              frame.grid.resolution, None) > MAX_WINDOW
            predicted = np.array([tr.mean[:2] for tr in self.tracks]).reshape(-1, 2)   # before any update
            self.update_tracks(self.tracks, frame, [np.delete(predicted, i, axis=0) for i in range(len(self.tracks))])
        else:
            used = self._update_on_regions(xy, sensor_pose)
        rep.seen = sum(tr.seen for tr in self.tracks)
        rep.missed = len(self.tracks) - rep.seen
        t2 = time.perf_counter()
        imaged = frame is not None and not frame.empty
        if frame is not None and imaged:
            rep.reseeded = self._reseed(xy, covs)
            self._templates(frame.windows)
            rep.outside = self._coverage(frame)
        self._count_detections(xy, covs)
        rep.ended, rep.ended_outside = self._end()
        if imaged or frame is None:     # a particle track's template needs image data at its birth
            rep.born = self._births(xy, covs, frame, used)
        for tr in self.tracks:
            if not tr.confirmed and tr.hits >= self.config.birth.confirm_hits:
                tr.confirmed = True
        rep.tracks = len(self.tracks)
        rep.confirmed = sum(tr.confirmed for tr in self.tracks)
        if frame is not None:
            rep.mf = sum(tr.seen and tr.fusion == MF for tr in self.tracks)
            rep.wf = sum(tr.seen and tr.fusion == WF for tr in self.tracks)
        rep.seconds = {'predict': t1 - t0, 'update': t2 - t1, 'manage': time.perf_counter() - t2}
        self.report = rep
        return tracks_to_records(self.tracks)

    def records(self) -> np.ndarray:
        """The current tracks as GPF_TRACK_DTYPE records."""
        return tracks_to_records(self.tracks) if self.tracks else np.zeros(0, GPF_TRACK_DTYPE)

    # -- per frame and per track -----------------------------------------------------------------
    def prepare(self, image: np.ndarray, grid: ImageGrid) -> Frame:
        """The frame's image ready for every track's update: block-averaged to the cues' pixel
        (module docstring), padded for window lookups, and its background features (the median
        window, :meth:`.cues.CueModel.background`). The frame's grid is that of the cues' pixels."""
        return self._prepare(check_image(image, grid), grid)

    def _prepare(self, img: np.ndarray, grid: ImageGrid) -> Frame:
        valid = np.isfinite(img) & (img > 0)
        factor = coarsening(self.config.cues.pixel, grid.resolution)
        if factor > 1:
            img, grid = coarsen(img, valid, grid, factor)
            valid = img > 0
        else:
            img = np.where(valid, img, 0.0)
        n = window_pixels(self.config.cues.window, grid.resolution)
        if not valid.any():
            return Frame(grid, None, None, n)
        wi = WindowImage(img, self.feature_config, n)
        return Frame(grid, wi, self.cues.background(wi, grid, valid), n)

    def predict_track(self, tr: GpfTrack, dt: float) -> None:
        """Move one track ``dt`` seconds on (its filter's prediction)."""
        self.filter.predict([tr], dt, self.config.motion.noise, self.config.particles, self.rng)

    def update_track(self, tr: GpfTrack, frame: Frame, others: np.ndarray | None = None) -> None:
        """Update one (predicted) track on a prepared frame (step 2 of §4.2.3); a frame without data
        or without the target is a miss (step 3). ``others (N, 2)``: the other tracks' predicted
        positions, for the ``crossing`` switch of adaptive fusion (:mod:`.fusion`)."""
        self.update_tracks([tr], frame, [others])

    def update_tracks(self, tracks: list[GpfTrack], frame: Frame, others: list[np.ndarray | None]) -> None:
        """:meth:`update_track` of several tracks on one frame, their window lookups batched;
        the same result as updating them one after the other."""
        if not tracks:
            return
        if frame.windows is None or frame.background is None:   # both None on an image without data
            for tr in tracks:
                self._miss(tr)
            return
        wi, grid, res = frame.windows, frame.grid, frame.grid.resolution
        fresh = [tr for tr in tracks if tr.template is None]
        if fresh:   # the cue set changed: measure the template where the track is
            values = self.cues.values(wi, grid, np.array([tr.mean[:2] for tr in fresh]), frame.window,
                                      np.arange(len(fresh)))
            for j, tr in enumerate(fresh):
                tr.template = values[:, j]
        k, n = self.config.particles, len(tracks)
        particles = self.filter.particles(tracks, k, self.rng)
        xy = np.concatenate([p[:, :2] for p in particles])
        values = self.cues.values(wi, grid, xy, frame.window, np.repeat(np.arange(n), k))
        values = values.reshape(self.cues.m, n, k).transpose(1, 0, 2)                    # (n, m, K)
        d2 = self.cues.distances2(values, np.array([tr.template for tr in tracks]))
        f = self.config.fusion
        crowded = [f.mode == 'af' and f.switch == 'crossing' and second_target(tr.mean, tr.cov, others[i], f.gate)
                   for i, tr in enumerate(tracks)]
        # Positions as views of whole particle rows: the layout each track's fuse would see.
        fusions = fuse_many(self.cues.log_likelihoods(d2), np.stack(particles)[:, :, :2], self.thresholds, f.mode,
                            np.array(crowded))
        floor = max(res * res / 12.0, self.config.min_std ** 2)
        posteriors = []
        for i, tr in enumerate(tracks):
            w, mean, cov = self.filter.posterior(tr, particles[i], fusions[i].log_likelihood, floor)
            posteriors.append((fusions[i], w, mean, cov))
        observed_all = self.cues.values(wi, grid, np.array([post[2][:2] for post in posteriors]), frame.window,
                                        np.arange(n))
        lost = self.config.lost
        for i, tr in enumerate(tracks):
            fused, w, mean, cov = posteriors[i]
            observed = observed_all[:, i]
            template = cast(np.ndarray, tr.template)   # measured above where it was missing
            match = float(self.cues.match(self.cues.distances2(observed[:, None], template))[0])
            distinct = float(self.cues.match(self.cues.distances2(frame.background[:, None], template))[0])
            tr.match, tr.distinct, tr.last_weights = match, distinct, w
            tr.inverse_spread, tr.a = fused.inverse_spread, fused.a
            if not (distinct > lost.distinct and match < lost.ratio * distinct):
                self._miss(tr)
                continue
            tr.mean, tr.cov, tr.fusion = mean, cov, fused.mode
            self._hit(tr)
            tr.observed = observed
            self.filter.accepted(tr, particles[i], w, floor, self.rng)

    def _update_on_regions(self, xy: np.ndarray, sensor_pose: tuple[float, float, float] | None) -> np.ndarray:
        """The update of a filter on regions (:meth:`.filters.Ekf.update_on_regions`, the sonar at
        the origin looking along x if its pose is unknown); returns which regions were used."""
        sensor = cast(tuple[float, float, float], tuple(float(v) for v in (sensor_pose or (0.0, 0.0, 0.0))))
        pairs = self.filter.update_on_regions(self.tracks, xy, sensor)
        used = np.zeros(len(xy), bool)
        for i, tr in enumerate(self.tracks):
            k = pairs.get(i)
            if k is None:
                self._miss(tr)
            else:
                self._hit(tr)
                used[k] = True
        return used

    def _hit(self, tr: GpfTrack) -> None:
        tr.seen, tr.misses = True, 0
        tr.last_seen = tr.stamp

    def _count_detections(self, xy: np.ndarray, covs: np.ndarray) -> None:
        """Count a detection for every track that saw its target in this frame and explains one of
        its regions (:func:`.management.explains`): the hits that confirm a track."""
        if not self.tracks or len(xy) == 0:
            return
        means = np.array([tr.mean[:2] for tr in self.tracks])
        pcov = np.array([tr.cov[:2, :2] for tr in self.tracks])
        at = np.any(explains(xy, means, pcov, self.config.birth, covs, self.config.birth.separation), axis=1)
        for tr, detected in zip(self.tracks, at, strict=True):
            if tr.seen and detected:
                tr.hits += 1

    def _miss(self, tr: GpfTrack) -> None:
        tr.seen = False
        tr.misses += 1
        tr.cov = widen(tr.cov, self.config.lost)
        self.filter.missed(tr, self.config.lost.inflation)

    # -- management -----------------------------------------------------------------------------
    def _templates(self, wi: WindowImage | None) -> None:
        if wi is None or not self.tracks:
            return
        positions = np.array([tr.mean[:2] for tr in self.tracks])
        for i, tr in enumerate(self.tracks):
            if not tr.seen or tr.observed is None or tr.template is None:
                continue
            others = np.delete(positions, i, axis=0)
            if template_may_update(tr.match, tr.mean[:2], others, self.config.template):
                tr.template = blend_template(tr.template, tr.observed, self.config.template.rate)
                tr.template_updates += 1

    def _coverage(self, frame: Frame) -> int:
        """Mark the tracks whose estimate is outside the sonar's coverage (no pixel with data in its
        window, :mod:`.management`); returns how many are. A frame without data changes nothing."""
        if frame.windows is None or not self.tracks:
            return 0
        xy = np.array([tr.mean[:2] for tr in self.tracks])
        r, c = frame.grid.point_to_pixel(xy[:, 0], xy[:, 1])
        mean = frame.windows.features(pixel_index(r), pixel_index(c), frame.window, (3,))[:, 0]
        outside = 0
        for tr, m in zip(self.tracks, mean):
            if m > 0.0:              # pixels without data are 0, so a mean of 0 means none has data
                tr.outside_since = None
            else:
                outside += 1
                if tr.outside_since is None:
                    tr.outside_since = tr.stamp
        return outside

    def _end(self) -> tuple[int, int]:
        """End the tracks lost too long or outside the coverage too long; returns how many ended, and
        how many of them for leaving the coverage."""
        lost = self.config.lost
        gone = [left_coverage(tr.outside_since, tr.stamp, lost) for tr in self.tracks]
        keep = [tr for tr, out in zip(self.tracks, gone)
                if not out and not should_end(tr.confirmed, tr.last_seen, tr.stamp, lost)]
        ended = len(self.tracks) - len(keep)
        self.tracks = keep
        return ended, sum(gone)

    def _reseed(self, xy: np.ndarray, covs: np.ndarray) -> int:
        """Lost tracks take up free regions in their gate (:mod:`.management`), confirmed tracks
        first."""
        return self._reseed_group(xy, covs, True) + self._reseed_group(xy, covs, False)

    def _reseed_group(self, xy: np.ndarray, covs: np.ndarray, confirmed: bool) -> int:
        lost = [tr for tr in self.tracks if not tr.seen and tr.confirmed == confirmed]
        if not lost or len(xy) == 0:
            return 0
        c = self.config.birth
        seen = [tr for tr in self.tracks if tr.seen]
        means = np.array([tr.mean[:2] for tr in seen]).reshape(-1, 2)
        pcov = np.array([tr.cov[:2, :2] for tr in seen]).reshape(-1, 2, 2)
        free = np.flatnonzero(unexplained(xy, means, pcov, c, covs, c.separation))
        if free.size == 0:
            return 0
        pairs = reseed_pairs(xy[free], np.array([tr.mean[:2] for tr in lost]),
                             np.array([tr.cov[:2, :2] for tr in lost]), covs[free], self.config.lost.refind_gate)
        H = np.eye(2, 4)
        R = np.eye(2) * self.config.lost.refind_sigma ** 2
        for i, j in pairs:
            tr, r = lost[i], free[j]
            # The region measures the position: a Kalman update of the widened prediction, which
            # also corrects the velocity through their correlation.
            tr.mean, tr.cov = kalman_update(tr.mean, tr.cov, xy[r] - tr.mean[:2], H, R)
            self._hit(tr)
            tr.match, tr.observed = 0.0, None
            self.filter.restart(tr, self.config.particles, self.rng)
        return len(pairs)

    def _births(self, xy: np.ndarray, covs: np.ndarray, frame: Frame | None, used: np.ndarray) -> int:
        """Tentative tracks on the regions no track explains and no update used, one per
        ``birth.separation`` (:mod:`.management`), up to ``birth.max_tracks`` tracks; a particle
        track takes its template from the frame (``frame`` None: a filter without templates)."""
        c = self.config.birth
        if len(xy) == 0:
            return 0
        means = np.array([tr.mean[:2] for tr in self.tracks]).reshape(-1, 2)
        pcov = np.array([tr.cov[:2, :2] for tr in self.tracks]).reshape(-1, 2, 2)
        free = np.flatnonzero(unexplained(xy, means, pcov, c, covs, c.separation) & ~used)
        free = free[spaced(xy[free], c.separation)]
        room = max(0, c.max_tracks - len(self.tracks))
        free = free[:room]
        if free.size == 0:
            return 0
        templates = (np.zeros((0, free.size)) if frame is None or frame.windows is None
                     else self.cues.values(frame.windows, frame.grid, xy[free], frame.window))
        stamp = cast(float, self.stamp)   # births come after the frame's stamp is taken
        for j, i in enumerate(free):
            mean = np.array([xy[i, 0], xy[i, 1], 0.0, 0.0])
            tr = GpfTrack(track_id=self.next_id, mean=mean, cov=covs[i], template=templates[:, j],
                          born=stamp, stamp=stamp, last_seen=stamp)
            self.next_id += 1
            self.filter.restart(tr, self.config.particles, self.rng)
            tr.confirmed = tr.hits >= c.confirm_hits
            self.tracks.append(tr)
        return int(free.size)

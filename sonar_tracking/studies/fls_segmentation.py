"""Simulated FLS frames with ground truth, and how segmentation is scored against it.

:func:`simulate_frames` runs a scenario of :mod:`sonar_tracking.sim` through a
:class:`~..fls.pipeline.FlsProcessor` (:func:`~.fls_frames.processed_frames`) and labels every
frame with each target's noise-free echo in that frame (``SeaKingSonar.render_mean`` for that
target alone), painted onto the frame's pixels:

* the target's **peak SNR** in the frame: the largest ratio of its mean echo to the mean
  reverberation over all cells of the sweep (aspect, range and beam position included);
* its **footprint**: the pixels where its echo is at least ``footprint_db`` above the
  reverberation mean (multipath ghost included), grown by ``match_distance``.

A region is **on** a target when it has a pixel in the target's footprint; a target is **found**
when a region is on it; a region on no target is a **false region**; regions beyond the first on a
target are **duplicates** (unjoined fragments). The frame also carries the raw sectors painted
without any processing, for the plain baseline (:func:`plain_segmentation`).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import cv2
import numpy as np

from sonar_tracking.core.fls.filters import median_blur
from sonar_tracking.core.fls.image import canvas_for, grid_image
from sonar_tracking.core.fls.pipeline import FlsConfig, FlsFrame, FlsProcessor
from sonar_tracking.core.fls.segmentation import threshold_components
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.sim import SeaKingSonar
from sonar_tracking.studies.fls_frames import processed_frames, simulator_for

__all__ = ['TargetTruth', 'LabelledFrame', 'simulate_frames', 'match_regions', 'FrameScore', 'Score',
           'score_frames', 'plain_segmentation', 'PlainConfig', 'RegionDataset', 'region_dataset']


@dataclass(eq=False)
class TargetTruth:
    """One target in one frame: id, shape name, peak SNR [dB], footprint (bool, frame grid)."""

    target_id: int
    shape: str
    snr_db: float
    footprint: np.ndarray


@dataclass(eq=False)
class LabelledFrame:
    """A processed frame, the raw (unfiltered) image on the same pixels, and the targets' truth."""

    scenario: str
    seed: int
    frame: FlsFrame
    raw: np.ndarray
    targets: list[TargetTruth]


def simulate_frames(scenario: str, seed: int, config: FlsConfig | None = None, *, preset: str = '',
                    first: int = 0, every: int = 1, max_frames: int | None = None, footprint_db: float = 0.0,
                    match_distance: float = 0.5, **sim_overrides) -> Iterator[LabelledFrame]:
    """Frames (sweeps) ``first, first + every, ...`` of a SeaKing scenario, processed and labelled
    (at most ``max_frames``).

    ``seed`` seeds the simulator; ``sim_overrides`` are flat SimConfig settings (``snr_db=15``).
    """
    sim = simulator_for(scenario, seed, preset, **sim_overrides)
    twin = SeaKingSonar(sim.config.seaking, sim.config.sector_size, sim.sensor.amplitude)
    processor = FlsProcessor(config)
    shapes = {t.target_id: t.shape.name for t in sim.scene.targets}
    index = emitted = 0
    level = 10.0 ** (footprint_db / 10.0)
    grow = int(math.ceil(match_distance / processor.config.image.resolution))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * grow + 1, 2 * grow + 1)) if grow > 0 else None

    def truth_maps(sector) -> dict:
        """Per target, its noise-free SNR map in this sector (only for frames that are wanted)."""
        plan = twin.plan()
        # A sector belongs to frame ``index``, or to the next one when it starts a sweep whose
        # predecessor is only emitted now.
        maps = {}
        if wanted_frame(index, first, every) or wanted_frame(index + 1, first, every):
            for target in sim.scene.targets:
                reverb, echoes, _ = twin.render_mean(sim.scene, plan, targets=[target])
                snr = echoes / reverb
                if plan.direction < 0:  # columns in increasing bearing, as in the sector
                    snr = snr[:, ::-1]
                if snr.max() > 1e-3:
                    maps[target.target_id] = snr.astype(np.float32)
        return maps

    if max_frames is not None and max_frames <= 0:
        return
    for frame, members in processed_frames(sim, processor, truth_maps):
        if wanted_frame(index, first, every):
            yield _label(scenario, seed, frame, members, shapes, level, kernel)
            emitted += 1
        index += 1
        if max_frames is not None and emitted >= max_frames:
            return


def wanted_frame(index: int, first: int, every: int) -> bool:
    return index >= first and (index - first) % every == 0


def _label(scenario: str, seed: int, frame: FlsFrame, members: list[tuple], shapes: dict[int, str], level: float,
           kernel: np.ndarray | None) -> LabelledFrame:
    raw_canvas = canvas_for(frame.grid)
    peaks: dict[int, float] = {}
    canvases = {}
    for sector, maps in members:
        raw_canvas.paint(sector.amplitudes, sector.geometry, sector.pose)
        for tid, snr in maps.items():
            peaks[tid] = max(peaks.get(tid, 0.0), float(snr.max()))
            canvas = canvases.get(tid)
            if canvas is None:
                canvas = canvases[tid] = canvas_for(frame.grid, fill=0.0)
            sub, geom = _crop(snr, sector.geometry)
            canvas.paint(sub, geom, sector.pose, hold_max=True)
    raw, _ = grid_image(raw_canvas)
    targets = []
    for tid, canvas in canvases.items():
        echo, _ = grid_image(canvas)
        fp = (echo >= level).astype(np.uint8)
        if kernel is not None and fp.any():
            fp = cv2.dilate(fp, kernel)
        targets.append(TargetTruth(tid, shapes[tid], 10.0 * math.log10(peaks[tid]), fp.astype(bool)))
    return LabelledFrame(scenario, seed, frame, raw, targets)


def _crop(values: np.ndarray, geometry: SectorGeometry) -> tuple[np.ndarray, SectorGeometry]:
    """The cells of a truth map that hold echo (one cell of margin), with their geometry: painting
    only those is much cheaper than painting the whole sector."""
    rows = np.flatnonzero(values.max(axis=1) > 0)
    cols = np.flatnonzero(values.max(axis=0) > 0)
    if rows.size == 0:
        return values[:1, :1], dataclasses.replace(geometry, n_bins=1, n_beams=1, range_max=geometry.range_min)
    i0, i1 = max(rows[0] - 1, 0), min(rows[-1] + 1, geometry.n_bins - 1)
    j0, j1 = max(cols[0] - 1, 0), min(cols[-1] + 1, geometry.n_beams - 1)
    r, b = geometry.ranges(), geometry.bearings()
    geom = dataclasses.replace(geometry, angle_min=float(b[j0]), n_beams=int(j1 - j0 + 1), range_min=float(r[i0]),
                               range_max=float(r[i1]), n_bins=int(i1 - i0 + 1))
    return values[i0:i1 + 1, j0:j1 + 1], geom


@dataclass
class FrameScore:
    """Matching of one frame's regions to its targets."""

    found: dict[int, bool]
    snr_db: dict[int, float]
    false_regions: int
    duplicates: int
    region_target: np.ndarray  # per region: target id, 0 = on none, -1 = on several


def match_regions(labels: np.ndarray, n: int, targets: list[TargetTruth]) -> FrameScore:
    """Which regions are on which targets (see module docstring)."""
    hit = np.zeros((n + 1, len(targets)), bool)
    for k, t in enumerate(targets):
        hit[np.unique(labels[t.footprint]), k] = True
    hit = hit[1:]
    on = hit.sum(axis=1)
    region_target = np.zeros(n, np.int64)
    for k, t in enumerate(targets):
        region_target[hit[:, k] & (on == 1)] = t.target_id
    region_target[on > 1] = -1
    found = {t.target_id: bool(hit[:, k].any()) for k, t in enumerate(targets)}
    return FrameScore(found=found, snr_db={t.target_id: t.snr_db for t in targets},
                      false_regions=int((on == 0).sum()),
                      duplicates=int(hit.sum() - sum(found.values())), region_target=region_target)


@dataclass
class Score:
    """Detection statistics over frames, for targets of at least ``min_snr_db``."""

    frames: int = 0
    targets: int = 0
    found: int = 0
    false_regions: int = 0
    duplicates: int = 0
    missed: list = field(default_factory=list)

    @property
    def detection_rate(self) -> float:
        return self.found / self.targets if self.targets else math.nan

    @property
    def false_per_frame(self) -> float:
        return self.false_regions / self.frames if self.frames else math.nan

    @property
    def duplicates_per_frame(self) -> float:
        return self.duplicates / self.frames if self.frames else math.nan

    def add(self, s: FrameScore, min_snr_db: float, where: str = '') -> None:
        self.frames += 1
        self.false_regions += s.false_regions
        self.duplicates += s.duplicates
        for tid, ok in s.found.items():
            if s.snr_db[tid] >= min_snr_db:
                self.targets += 1
                self.found += ok
                if not ok:
                    self.missed.append((where, tid, round(s.snr_db[tid], 1)))

    def as_dict(self) -> dict:
        return {'frames': self.frames, 'targets': self.targets, 'found': self.found,
                'detection_rate': self.detection_rate, 'false_regions': self.false_regions,
                'false_per_frame': self.false_per_frame, 'duplicates_per_frame': self.duplicates_per_frame}


@dataclass(frozen=True)
class PlainConfig:
    """The plain baseline: median blur of ``ksize`` pixels, one threshold, connected components."""

    ksize: int = 3
    threshold_db: float = 5.0
    min_pixels: int = 4


def plain_segmentation(raw: np.ndarray, config: PlainConfig = PlainConfig()) -> tuple[np.ndarray, int]:
    """The baseline on a raw painted image: scale so the background mean is 1 (the median of the
    painted pixels over ln 2, as the modified filter's level but for the whole image at once),
    plain median blur, threshold at ``threshold_db``, 8-connected components."""
    painted = np.isfinite(raw)
    scale = float(np.median(raw[painted])) / math.log(2.0) if painted.any() else 1.0
    img = median_blur(np.where(painted, raw / max(scale, 1e-30), np.nan), config.ksize)
    return threshold_components(img, 10.0 ** (config.threshold_db / 10.0), config.min_pixels)


def score_frames(frames: list[LabelledFrame], min_snr_db: float = 10.0,
                 plain: PlainConfig | None = None) -> Score:
    """Score the frames' own regions, or with ``plain`` those of the plain baseline on the raw image."""
    score = Score()
    for lf in frames:
        if plain is None:
            labels, n = lf.frame.labels, len(lf.frame.regions)
        else:
            labels, n = plain_segmentation(lf.raw, plain)
        score.add(match_regions(labels, n, lf.targets), min_snr_db, f'{lf.scenario}/{lf.seed}@{lf.frame.stamp:.2f}')
    return score


@dataclass(eq=False)
class RegionDataset:
    """Labelled regions: features ``(n, 30)`` (f01..f30), class name per region (a target shape or
    ``'clutter'``), and the index of the frame each came from (to split by frame)."""

    features: np.ndarray
    labels: np.ndarray
    frame: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)

    def subset(self, mask: np.ndarray) -> RegionDataset:
        return RegionDataset(self.features[mask], self.labels[mask], self.frame[mask])

    def counts(self) -> dict[str, int]:
        names, n = np.unique(self.labels, return_counts=True)
        return {str(k): int(v) for k, v in zip(names, n)}


def region_dataset(frames: list[LabelledFrame]) -> RegionDataset:
    """Every region of the frames with the shape of the one target it is on, ``'clutter'`` if on
    none; regions on several targets (crossings) and regions with non-finite features are left out."""
    from sonar_tracking.core.records import FEATURE_NAMES
    feats, labels, index = [], [], []
    for i, lf in enumerate(frames):
        regions = lf.frame.regions
        if len(regions) == 0:
            continue
        m = match_regions(lf.frame.labels, len(regions), lf.targets)
        shapes = {t.target_id: t.shape for t in lf.targets}
        x = np.stack([regions[name] for name in FEATURE_NAMES], axis=1)
        for k in range(len(regions)):
            tid = int(m.region_target[k])
            if tid < 0 or not np.isfinite(x[k]).all():
                continue
            feats.append(x[k])
            labels.append(shapes[tid] if tid > 0 else 'clutter')
            index.append(i)
    return RegionDataset(np.array(feats, dtype=np.float64).reshape(-1, 30), np.array(labels, dtype=object),
                         np.array(index, dtype=np.int64))

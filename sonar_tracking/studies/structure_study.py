"""Tracks on static structure: how many confirmed tracks sit on walls, piles, the seabed band or the
ringdown of a structured scene, next to how well the moving targets are tracked.

:func:`run_structure_study` runs a structured scenario (``*_structured``, ``structure_only``)
through a front end and its tracker for a number of frames: on a SeaKing, the FLS pipeline
(``fls_features``: :class:`~..fls.pipeline.FlsProcessor`) and the GPF tracker (AF fusion, or any
:data:`~.fls_study.METHODS` entry); on the harbour sonar, ``active_detector``
(:class:`~..detection.ActiveDetector`, ESC on, rho_D 2.21e-5 as in the ESC study) and the IMM-IPDA
tracker with the CV/CCW/CW models. The simulator's 8-bit dB output is decoded with
``core.intensity`` first (:func:`~.fls_frames.sim_amplitudes`).

:func:`count_structure_tracks` classifies every confirmed track by the positions it had while
confirmed:

* **on a target** if it came within ``clearance`` of a true target in any of those frames;
* **on structure** otherwise, if every position lies within ``near`` of structure
  (:func:`structure_distance`: a wall or pile scatterer, the seabed band's ranges, or the ranges
  where the ringdown is above the reverberation mean);
* **elsewhere** otherwise (a false track in open water, or one that drifted off structure).

Targets are scored per frame: tracked when a confirmed track lies within ``gate`` of the target;
CTTR is the share of (frame, target) pairs tracked and CLE the mean distance to the nearest
confirmed track over those pairs (a simple reading of FLS eq. 19 and ESC §5's CTTR, for comparing
a structured scene with its plain twin; :mod:`.fls_study` and :mod:`.esc_study` score the papers'
studies).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from sonar_tracking.core.detection import ActiveDetector, DetectorConfig
from sonar_tracking.core.fls import FlsConfig
from sonar_tracking.core.tracking.config import TrackerConfig
from sonar_tracking.core.tracking.detections import detections_to_measurements
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker
from sonar_tracking.sim import SimConfig, Simulator
from sonar_tracking.sim.structure import Structure
from sonar_tracking.studies.fls_frames import sim_amplitudes, simulate_tracking_frames
from sonar_tracking.studies.fls_study import FlsStudy, run_methods

__all__ = ['StructureCounts', 'structure_distance', 'count_structure_tracks', 'run_structure_study',
           'STRUCTURE_REJECTION', 'plain_twin', 'combine']

#: Desired clutter density of the harbour pipeline (the ESC study's rho_D) [1/m^2].
HARBOUR_RHO_D = 2.21e-5

#: Static-structure rejection for the simulated sensors (``core.structure``), as a sensor preset
#: would set it: shape gates a few target sizes long, and the persistent-echo background. The
#: harbour sonar confirms a track within about four 1 s scans, so its cells must count as persistent
#: sooner (``min_echo_time`` 3 s); its 17 m cells make walls long in cells but its targets short.
STRUCTURE_REJECTION: dict[str, dict[str, Any]] = {
    'seaking': {'structure.enabled': True, 'structure.max_length': 6.0, 'structure.elongated_length': 2.5,
                'structure.max_aspect': 4.0},
    # persistence 0.1: the seabed band's weak edge echoes in bursts of a few scans, seldom enough to
    # stay under 0.2 and long enough for the tracker to confirm (3 tracks in 100 scans, seed 1)
    'harbour': {'structure.enabled': True, 'structure.min_echo_time': 3.0, 'structure.max_length': 120.0,
                'structure.elongated_length': 80.0, 'structure.max_aspect': 4.0, 'structure.persistence': 0.1},
}


def combine(counts: list[StructureCounts]) -> StructureCounts:
    """The counts of several runs as one: sums, CTTR weighted by frames, CLE by tracked frames."""
    frames = sum(c.frames for c in counts)
    with_targets = [c for c in counts if not math.isnan(c.cttr)]
    tracked = [(c.cttr * c.frames, c.cle) for c in with_targets if not math.isnan(c.cle)]
    weight = sum(w for w, _ in tracked)
    return StructureCounts(
        frames=frames, confirmed_tracks=sum(c.confirmed_tracks for c in counts),
        on_target=sum(c.on_target for c in counts), on_structure=sum(c.on_structure for c in counts),
        elsewhere=sum(c.elsewhere for c in counts),
        structure_track_ids=tuple(i for c in counts for i in c.structure_track_ids),
        cttr=(sum(c.cttr * c.frames for c in with_targets) / sum(c.frames for c in with_targets)
              if with_targets else math.nan),
        cle=sum(w * e for w, e in tracked) / weight if weight else math.nan)


def plain_twin(scenario: str) -> str | None:
    """The structure-free scenario a structured one is built on (``fls8_structured`` -> ``fls8``),
    or None (``structure_only`` has no twin)."""
    return scenario[:-len('_structured')] if scenario.endswith('_structured') else None


@dataclass(frozen=True)
class StructureCounts:
    """Confirmed tracks by what they sat on, and target tracking quality, over ``frames`` frames."""

    frames: int
    confirmed_tracks: int
    on_target: int
    on_structure: int
    elsewhere: int
    structure_track_ids: tuple[int, ...]
    cttr: float      # share of (frame, target) pairs with a confirmed track within the gate (nan: no target)
    cle: float       # mean distance to the nearest confirmed track where tracked [m] (nan: never tracked)


def structure_distance(xy: np.ndarray, structure: Structure, sensor_xy: tuple[float, float],
                       first_range: float = 0.0) -> np.ndarray:
    """Distance [m] of world points ``(N, 2)`` from the scene's structure seen from ``sensor_xy``.

    The nearest of: a wall or pile scatterer; the seabed band (a range interval from the sensor);
    the ringdown zone, ranges up to where the ringdown falls to the reverberation mean
    (``first_range + ringdown_length * ln(10^(ringdown_db / 10))``).
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    out = np.full(len(xy), np.inf)
    points = [s.points for s in structure.scatterers()]
    if points and len(xy):
        out, _ = cKDTree(np.concatenate(points)).query(xy)
        out = np.asarray(out, dtype=float)
    r = np.hypot(xy[:, 0] - sensor_xy[0], xy[:, 1] - sensor_xy[1])
    c = structure.config
    band = np.maximum(0.0, np.maximum(c.seabed_range_min - r, r - c.seabed_range_max))
    out = np.minimum(out, band)
    if c.ringdown_db > 0:
        reach = first_range + c.ringdown_length * c.ringdown_db * math.log(10.0) / 10.0
        out = np.minimum(out, np.maximum(0.0, r - reach))
    return out


def count_structure_tracks(records: list[np.ndarray], truths: list[np.ndarray],
                           distance: Callable[[int, np.ndarray], np.ndarray], near: float, clearance: float,
                           gate: float) -> StructureCounts:
    """Classify the confirmed tracks of ``records`` (per frame: arrays with ``track_id, x, y,
    confirmed``) against ``truths`` (per frame: ``(G, 2+)`` target positions) and structure
    (``distance(frame, xy) -> (N,)`` metres); see the module docstring."""
    if len(records) != len(truths):
        raise ValueError(f'{len(records)} frames of tracks but {len(truths)} of truth')
    on_target: set[int] = set()
    off_structure: set[int] = set()
    seen: set[int] = set()
    tracked, pairs, errors = 0, 0, []
    for k, (rec, truth) in enumerate(zip(records, truths)):
        conf = rec[rec['confirmed'] != 0] if len(rec) else rec
        xy = np.column_stack([conf['x'], conf['y']]) if len(conf) else np.zeros((0, 2))
        t = np.asarray(truth, dtype=float)[:, :2]
        d = np.linalg.norm(xy[:, None, :] - t[None, :, :], axis=-1)  # tracks x targets
        ids = [int(i) for i in conf['track_id']] if len(conf) else []
        seen.update(ids)
        if len(ids):
            near_target = (d < clearance).any(axis=1) if t.size else np.zeros(len(ids), bool)
            on_target.update(i for i, hit in zip(ids, near_target) if hit)
            far = distance(k, xy) > near
            off_structure.update(i for i, f in zip(ids, far) if f)
        pairs += len(t)
        if len(t) and len(ids):
            nearest = d.min(axis=0)
            ok = nearest <= gate
            tracked += int(ok.sum())
            errors.extend(nearest[ok].tolist())
    structure_ids = sorted(seen - on_target - off_structure)
    return StructureCounts(frames=len(records), confirmed_tracks=len(seen), on_target=len(on_target),
                           on_structure=len(structure_ids), elsewhere=len(seen - on_target) - len(structure_ids),
                           structure_track_ids=tuple(structure_ids),
                           cttr=tracked / pairs if pairs else math.nan,
                           cle=float(np.mean(errors)) if errors else math.nan)


def run_structure_study(scenario: str, seed: int, frames: int, preset: str = '', method: str = 'af',
                        near: float | None = None, clearance: float | None = None, gate: float | None = None,
                        front_end: Mapping[str, Any] | None = None, **sim_overrides) -> StructureCounts:
    """Run ``frames`` frames (SeaKing sweeps or harbour scans) of a scenario through the front end and
    tracker of its sensor and count tracks on structure (module docstring); a scenario without
    structure (the plain twin of a structured one) has none on structure, and its CTTR and CLE are
    the baseline.

    ``front_end``: flat settings of the front end (``FlsConfig`` on a SeaKing, ``DetectorConfig`` on
    the harbour sonar), e.g. :data:`STRUCTURE_REJECTION`. Distances default to the sensor's scale:
    ``near`` 1 m, ``clearance`` 2 m, ``gate`` 1.5 m (the FLS study's) in the tank; 40, 100 and 100 m
    (a few 17 m cells) on the harbour sonar.
    """
    cfg = SimConfig.for_scenario(scenario, preset, **sim_overrides)
    harbour = cfg.is_harbour
    near = near if near is not None else (40.0 if harbour else 1.0)
    clearance = clearance if clearance is not None else (100.0 if harbour else 2.0)
    gate = gate if gate is not None else (100.0 if harbour else 1.5)
    front_end = dict(front_end or {})
    if harbour:
        records, truths, poses, sim = _harbour_tracks(cfg, seed, frames, DetectorConfig.from_flat(front_end))
        first_range = sim.sensor.geometry.range_min - 0.5 * cfg.harbour.cell_depth
    else:
        duration = frames * cfg.seaking.sweep_time + 1e-6
        tf = simulate_tracking_frames(scenario, seed, FlsConfig.from_flat(front_end), preset,
                                      **{**sim_overrides, 'duration': duration})
        records = run_methods(FlsStudy(scenario, methods=(method,), preset=preset), tf,
                              np.random.SeedSequence(seed))[method]
        truths = [f.truth for f in tf]
        poses = [f.frame.sensor_pose for f in tf]
        sim = Simulator(cfg, np.random.default_rng(seed))
        first_range = 0.0
    structure = sim.scene.structure

    def distance(k: int, xy: np.ndarray) -> np.ndarray:
        if structure is None:
            return np.full(len(xy), np.inf)
        return structure_distance(xy, structure, poses[k][:2], first_range)

    return count_structure_tracks(records, truths, distance, near, clearance, gate)


def _harbour_tracks(cfg: SimConfig, seed: int, frames: int, detector_config: DetectorConfig):
    """Per scan: IMM-IPDA track records, true positions and sonar poses; and the simulator."""
    sim = Simulator(cfg, np.random.default_rng(seed))
    detector = ActiveDetector(detector_config, HARBOUR_RHO_D)
    tracker = ImmIpdaTracker(TrackerConfig.from_flat({'imm.models': 'cv,ccw,cw'}))
    records, truths, poses = [], [], []
    for _ in range(frames):
        s = sim.next_sector()
        if s is None:
            break
        result = detector.process(sim_amplitudes(s, cfg.output), s.geometry, s.pose, stamp=s.stamp)
        z, R, rho, _ = detections_to_measurements(result.detections)
        records.append(tracker.step(s.stamp, z, R, rho))
        truths.append(sim.truth(s.stamp)[1])
        poses.append(s.pose)
    return records, truths, poses, sim

"""Imaging sonars in Monte Carlo runs: the simulated multibeam head, ``active_detector``'s CFAR front end
and the point trackers at frame rate, in process (no ROS), with each sensor preset's node settings.

One run (:func:`run_once`) renders a scenario of :mod:`sonar_tracking.sim.presets` (``imaging_*``) on a
simulated head (``oculus_m750d``, ``gemini_720``, ``aris3000``) with 8-bit dB output, as
``seaking_sim`` publishes it, and puts every frame through :class:`~..detection.ActiveDetector` and
one or more trackers (IMM-IPDA, IMM-JIPDA) set from the preset's parameter file
(``config/sensors/NAME.yaml``: the ``active_detector`` and ``imm_ipda_tracker`` sections, exactly as
``--params-file`` gives them to the nodes; ``intensity.coding: db`` for the simulator's frames, as
``config/stack_imaging.yaml`` sets it). Every tracker sees the same detections; ESC's
``esc.exclude_radius`` follows the first tracker's tracks (confirmed, or of existence at least
``esc.exclude_existence``), as the detector node follows the ``tracks`` topic.

**Reduced frames** (``scale`` s > 1): every s-th beam and bin (the Oculus's 512 x 1000 cells become
256 x 500 at s = 2) over the same fan and range, with the same beam width and pulse, and the preset's
settings counted in cells (CFAR strides, guards and reaches, merge distances) divided by s. The
physics of a cell (beam pattern, speckle, levels) is unchanged; a cell is coarser.

**Scoring**, per frame, against the targets inside the fan (range at most the range setting, bearing
within the field of view):

* *tracked*: a confirmed track within ``gate`` of the target; CTTR the share of (frame, target)
  pairs tracked; *detected* likewise for a detection (P_D);
* a confirmed track is *on a target* if, in any frame while confirmed, it came within
  ``clearance`` of a target (also one outside the fan); otherwise it is a *false confirmed track*;
* *duplicates*: (frame, target) pairs with more than one confirmed track within ``gate``;
* *track breaks* of a target: the number of times its tracking track (the nearest confirmed track
  within ``gate``) is a track it never had before, less one;
* *false detections*: detections farther than ``gate`` from every target (inside or outside the fan);
* GOSPA (:class:`~.evidence.GospaSpec`) between the targets in the fan and the confirmed tracks, mean
  over frames.

ESC is scored on the density it controls: the detector's ESC input per frame (``mean_density``) over
the desired density.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sonar_tracking.core.detection import ActiveDetector, DetectorConfig, tracked_positions
from sonar_tracking.core.fls.pipeline import FlsConfig, FlsProcessor
from sonar_tracking.core.tracking.config import TrackerConfig
from sonar_tracking.core.tracking.detections import detections_to_measurements
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker
from sonar_tracking.sim import SimConfig, Simulator
from sonar_tracking.sim.motion import ScriptedTrajectory
from sonar_tracking.sim.simulator import child_seeds
from sonar_tracking.studies.evidence import GospaSpec

__all__ = ['PARAMS_FILES', 'CELL_SETTINGS', 'ImagingRun', 'front_end', 'region_front_end', 'run_once', 'poisson_upper',
           'GOSPA', 'GATE', 'CLEARANCE']

#: The parameter file (config/sensors/NAME.yaml) of each simulated head.
PARAMS_FILES = {'oculus_m750d': 'oculus_m750d', 'gemini_720': 'gemini_720', 'aris3000': 'aris_didson'}
#: Settings counted in beams and in bins, divided by the scale of a reduced frame.
CELL_SETTINGS = {'beams': ('cfar.stride_beams', 'cfar.guard_beams', 'cfar.reach_beams', 'cells.merge_beams'),
                 'bins': ('cfar.stride_bins', 'cfar.guard_bins', 'cfar.reach_bins', 'cells.merge_bins')}
#: The region path's window sizes in cells (odd), divided by the scale and kept odd; its area in cells,
#: divided by the scale squared.
FLS_WINDOWS = ('filter.window_bins', 'filter.window_beams', 'filter.background_bins')
FLS_AREAS = ('segment.min_cells',)
#: A target is tracked (or detected) by a confirmed track (or detection) this close [m]: a diver is 1.8 m long.
GATE = 1.5
#: A confirmed track that never came this close to a target is false [m].
CLEARANCE = 3.0
#: GOSPA of the confirmed tracks against the targets in the fan.
GOSPA = GospaSpec(c=3.0, p=2.0, alpha=2.0)


def _node_settings(params_file: str, node: str) -> dict[str, Any]:
    from sonar_tracking.io import param_files
    from sonar_tracking.resources import config_path
    data = param_files.load(config_path(f'sensors/{params_file}.yaml'))
    return dict(param_files.parameters_for(data, node) or {})


def region_front_end(sensor: str, scale: int = 1, overrides: dict | None = None) -> FlsConfig:
    """The FLS region path's settings of ``sensor``'s preset file (its ``fls_features`` section) for
    frames reduced by ``scale`` (module docstring), then ``overrides`` (flat names)."""
    keys = {s.name for s in FlsConfig.settings()}
    flat = {k: v for k, v in _node_settings(PARAMS_FILES[sensor], 'fls_features').items() if k in keys}
    flat['intensity.coding'] = 'db'
    if scale > 1:
        for name in FLS_WINDOWS:
            if name in flat:
                flat[name] = max(1, int(flat[name]) // scale) | 1
        for name in FLS_AREAS:
            if name in flat:
                flat[name] = float(flat[name]) / scale ** 2
    flat.update(overrides or {})
    return FlsConfig.from_flat(flat)


def front_end(sensor: str, scale: int = 1, detector: dict | None = None,
              tracker: dict | None = None) -> tuple[DetectorConfig, TrackerConfig]:
    """The detector and tracker settings of ``sensor``'s preset file for frames reduced by ``scale``
    (module docstring), then ``detector`` / ``tracker`` overrides (flat names)."""
    det_keys = {s.name for s in DetectorConfig.settings()}
    trk_keys = {s.name for s in TrackerConfig.settings()}
    det = {k: v for k, v in _node_settings(PARAMS_FILES[sensor], 'active_detector').items() if k in det_keys}
    trk = {k: v for k, v in _node_settings(PARAMS_FILES[sensor], 'imm_ipda_tracker').items() if k in trk_keys}
    det['intensity.coding'] = 'db'
    if scale > 1:
        for names in CELL_SETTINGS.values():
            for name in names:
                if name in det:
                    det[name] = max(1, int(det[name]) // scale)
        for axis in ('beams', 'bins'):
            # The training reach must still pass the guard by at least one stride.
            g, s, r = (det.get(f'cfar.{k}_{axis}') for k in ('guard', 'stride', 'reach'))
            if g is not None and s is not None and r is not None and r < g + s:
                det[f'cfar.reach_{axis}'] = g + s
    det.update(detector or {})
    trk.update(tracker or {})
    return DetectorConfig.from_flat(det), TrackerConfig.from_flat(trk)


@dataclass(frozen=True)
class ImagingRun:
    """One kind of run: scenario, head, frame reduction, frames and overrides (flat settings as pairs).

    ``methods``: trackers fed with the same detections (``ipda``, ``jipda``); ``confirm``: ``(method,
    T_c)`` pairs, each tracker's confirmation threshold where given. ``start``: the scenario time of
    the first frame [s] (the first frame draws fresh speckle); < 0: drawn per run, uniform over the
    scenario. ``clutter_switch``:
    ``(frame, law, k_shape)`` changes the clutter law from that frame on. ``platform_speed`` > 0
    replaces the scenario's platform by one moving straight ahead at that speed [m/s] (speckle
    decorrelates frame to frame). ``series``: keep the per-frame ESC density and scale. ``path``:
    ``'cfar'`` (``active_detector``) or ``'regions'``: the FLS region path (``fls_features``, the
    preset's section with ``fls`` overrides), whose regions are scored as the detections and not tracked.
    """

    scenario: str
    sensor: str = 'oculus_m750d'
    scale: int = 1
    frames: int = 0
    detector: tuple = ()
    tracker: tuple = ()
    sim: tuple = ()
    methods: tuple[str, ...] = ('ipda',)
    confirm: tuple = ()
    start: float = 0.0
    clutter_switch: tuple | None = None
    platform_speed: float = 0.0
    series: bool = False
    path: str = 'cfar'
    fls: tuple = ()

    def configs(self) -> tuple[DetectorConfig, TrackerConfig]:
        return front_end(self.sensor, self.scale, dict(self.detector), dict(self.tracker))

    def sim_config(self) -> SimConfig:
        flat: dict[str, Any] = {'output.coding': 'db'}
        if self.scale > 1:
            base = SimConfig.for_scenario(self.scenario, self.sensor)
            flat['imaging.n_beams'] = max(1, base.imaging.n_beams // self.scale)
            flat['imaging.n_bins'] = max(2, base.imaging.n_bins // self.scale)
        flat.update(dict(self.sim))
        return SimConfig.for_scenario(self.scenario, self.sensor, **flat)


def _in_fan(xy: np.ndarray, pose: tuple[float, float, float], range_max: float, half_fov: float) -> np.ndarray:
    dx, dy = xy[:, 0] - pose[0], xy[:, 1] - pose[1]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    x, y = c * dx + s * dy, -s * dx + c * dy
    return (np.hypot(x, y) <= range_max) & (np.abs(np.arctan2(y, x)) <= half_fov)


class _Score:
    """Per-run tallies of one tracker (module docstring)."""

    def __init__(self) -> None:
        self.pairs = self.tracked = self.duplicates = 0
        self.gospa: list[float] = []
        self.on_target: set[int] = set()
        self.confirmed: set[int] = set()
        self.history: dict[int, list[int]] = {}

    def frame(self, truth_ids: np.ndarray, truth_xy: np.ndarray, seen: np.ndarray, tracks: np.ndarray) -> None:
        conf = tracks[tracks['confirmed'] != 0]
        cxy = np.stack([conf['x'], conf['y']], axis=-1).reshape(-1, 2)
        ids = conf['track_id'].astype(int)
        self.confirmed.update(ids.tolist())
        if len(cxy) and len(truth_xy):
            d = np.hypot(cxy[:, None, 0] - truth_xy[None, :, 0], cxy[:, None, 1] - truth_xy[None, :, 1])
            self.on_target.update(ids[(d <= CLEARANCE).any(axis=1)].tolist())
        else:
            d = np.zeros((len(cxy), len(truth_xy)))
        for j in np.flatnonzero(seen):
            self.pairs += 1
            near = np.flatnonzero(d[:, j] <= GATE) if len(cxy) else np.zeros(0, int)
            if len(near):
                self.tracked += 1
                self.duplicates += len(near) > 1
                own = int(ids[near[np.argmin(d[near, j])]])
                h = self.history.setdefault(int(truth_ids[j]), [])
                if own not in h:
                    h.append(own)
        self.gospa.append(GOSPA(truth_xy[seen], cxy).distance)

    def result(self, hours: float) -> dict:
        false = sorted(self.confirmed - self.on_target)
        return {'cttr': self.tracked / self.pairs if self.pairs else math.nan,
                'gospa': float(np.mean(self.gospa)) if self.gospa else math.nan,
                'false_tracks': len(false), 'hours': hours,
                'duplicates': self.duplicates / self.pairs if self.pairs else math.nan,
                'breaks': float(np.mean([len(h) - 1 for h in self.history.values()])) if self.history else 0.0,
                'targets_tracked': len(self.history)}


def run_once(run: ImagingRun, seed: np.random.SeedSequence) -> dict:
    """One run (module docstring): per method its scores, and the detector's (P_D, false detections
    per frame, ESC figures; with ``series`` the per-frame ESC density and scale)."""
    cfg = run.sim_config()
    sim = Simulator(cfg, np.random.default_rng(seed))
    frames = run.frames or int(round(cfg.duration * cfg.imaging.frame_rate))
    start = run.start
    if start < 0:
        span = max(cfg.duration - frames / cfg.imaging.frame_rate, 0.0)   # the simulator uses children 0, 1
        start = float(np.random.default_rng(child_seeds(seed, 3)[2]).uniform(0.0, span))
    sim.sensor.frame = int(round(start * cfg.imaging.frame_rate))
    if run.platform_speed > 0:
        sim.scene.platform = ScriptedTrajectory(0.0, 0.0, run.platform_speed, 0.0)
    dcfg, tcfg = run.configs()
    detector = ActiveDetector(dcfg)
    regions = FlsProcessor(region_front_end(run.sensor, run.scale, dict(run.fls))) if run.path == 'regions' else None
    confirm = dict(run.confirm)
    trackers = {m: ImmIpdaTracker(TrackerConfig.from_flat(
        {'association.method': m, **({'existence.confirm': confirm[m]} if m in confirm else {})}, base=tcfg))
        for m in run.methods}
    scores = {m: _Score() for m in run.methods}
    half_fov, range_max = math.radians(cfg.imaging.fov_deg) / 2, cfg.imaging.range_max
    tracked_xy = None
    pairs = detected = false_dets = n_frames = 0
    density, scale = [], []
    for k in range(frames):
        if run.clutter_switch is not None and k == run.clutter_switch[0]:
            sim.sensor.set_clutter(run.clutter_switch[1], run.clutter_switch[2])
        s = sim.next_sector()
        if s is None:
            break
        if regions is not None:
            found = [f.regions for f in regions.add_sector(s.amplitudes, s.geometry, s.pose, s.stamp)]
            det = np.concatenate(found) if found else np.zeros(0, [('x', float), ('y', float)])
        else:
            result = detector.process(s.amplitudes, s.geometry, s.pose, stamp=s.stamp, tracked_xy=tracked_xy)
            det = result.detections
        truth_ids, states = sim.truth(s.stamp)
        truth_xy = states[:, :2]
        seen = _in_fan(truth_xy, s.pose, range_max, half_fov)
        dxy = np.stack([det['x'], det['y']], axis=-1).reshape(-1, 2)
        if len(truth_xy) and len(dxy):
            dd = np.hypot(dxy[:, None, 0] - truth_xy[None, :, 0], dxy[:, None, 1] - truth_xy[None, :, 1])
            detected += int(np.count_nonzero((dd[:, seen] <= GATE).any(axis=0)))
            false_dets += int(np.count_nonzero((dd > GATE).all(axis=1)))
        else:
            false_dets += len(dxy)
        pairs += int(np.count_nonzero(seen))
        n_frames += 1
        if regions is not None:
            continue
        if run.series:
            density.append(result.mean_density)
            scale.append(result.threshold)
        z, R, rho, _ = detections_to_measurements(det)
        for i, (m, trk) in enumerate(trackers.items()):
            tracks = trk.step(s.stamp, z, R, rho)
            scores[m].frame(truth_ids, truth_xy, seen, tracks)
            if i == 0:
                tracked_xy = tracked_positions(tracks, dcfg.esc.exclude_existence)
    hours = n_frames / cfg.imaging.frame_rate / 3600.0
    out: dict[str, Any] = {m: scores[m].result(hours) for m in run.methods}
    out['detector'] = {'frames': n_frames, 'pd': detected / pairs if pairs else math.nan,
                       'false_per_frame': false_dets / n_frames if n_frames else math.nan,
                       'desired_density': detector.desired_density, 'final_scale': detector.threshold}
    if run.series:
        out['detector']['density'] = np.asarray(density, dtype=np.float32)
        out['detector']['scale'] = np.asarray(scale, dtype=np.float32)
    for m, trk in trackers.items():
        out[m]['confirm'] = trk.config.existence.confirm
    return out


def poisson_upper(count: int, exposure: float, level: float = 0.95) -> float:
    """One-sided upper confidence bound of a Poisson rate: ``count`` events in ``exposure`` (e.g.
    hours), ``chi2(level, 2 (count + 1)) / 2 / exposure`` (3.0 / exposure for no event at 95 %)."""
    from scipy import stats
    if exposure <= 0:
        return math.inf
    return float(stats.chi2.ppf(level, 2 * (count + 1)) / 2.0 / exposure)

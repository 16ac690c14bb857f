"""IMM-JIPDA against independent IMM-IPDA on two close targets: crossing and parallel.

A measurement-level simulation (no sectors, no detector): the harbour sonar of the ESC scenarios
(at :data:`~sonar_tracking.sim.presets.HARBOUR_SONAR_XY`, range std ``sigma_r`` 5 m, bearing
std ``sigma_theta`` 0.1 deg) looks at a square window centred 2500 m away, one scan per second.
Each target is detected with probability ``P_D``; its detection is the true range and bearing plus
Gaussian noise, converted to x, y with the covariance of eq. (10)
(:func:`~sonar_tracking.core.detection.convert_measurements`). Clutter is Poisson with density
``rho`` per m^2, uniform over the window, each clutter detection with the covariance of its own
range and bearing. Two targets closer than a resolution cell are still two detections (no
merged, unresolved detections): the simulation tests association, not resolution. With
``unresolved``, two targets both detected within one cell of each other give one detection at their
mean position instead (a crude model of a sonar that cannot resolve them; neither tracker models it).

Geometries (random per run):

* ``crossing``: two targets at the same speed whose tracks cross at the window centre at an angle
  uniform in ``crossing_deg`` (5-20 deg), at the middle scan; the pair heads in a uniform direction
  (100 scans at 5 m/s: even at 5 deg the targets are more than a cell apart at both ends);
* ``parallel``: two targets on parallel courses ``parallel_cells`` (2-4) resolution cells apart
  (the cell side ``sqrt(V_rc)``, ``V_rc = 12 sigma_r sigma_theta r``, 16.2 m at 2500 m), passing the
  window centre at the middle scan.

Both trackers (``association.method`` ``ipda`` and ``jipda``, otherwise identical: three IMM modes,
``P_D``, the true clutter density as a constant, the node's defaults) track the SAME detections of
each run. A run is a pure function of the study and its seed (all randomness from one
``numpy.random.Generator``).

Per run and method:

* ``gospa``: mean over scans of GOSPA (:func:`~.metrics.gospa`, ``p = 2``, ``alpha = 2``, cut-off
  ``gospa_c``) between the true positions and the confirmed tracks' positions, and its parts
  (mean missed targets and false tracks per scan);
* ``swaps``: on the scans where the targets are more than one cell apart, the times a target's
  assigned confirmed track (the GOSPA assignment within ``gospa_c``) is the track the other target
  was last assigned on such a scan (while they are closer, labels are ambiguous and not scored);
* ``coalescence``: fraction of the scans with the targets more than one cell apart in which both
  targets' nearest confirmed tracks are the same track, or two confirmed tracks within ``gospa_c``
  of a target lie within half a cell of each other (NaN for a run with no such scan);
* ``cttr``: fraction of (scan, target) with a confirmed true track (eqs. 47-48, ``P_{0|0}`` of a
  track started at the window centre).

:func:`summarise` gives the means and the paired per-run difference JIPDA - IPDA with its 95 %
interval (:func:`~.metrics.paired_difference`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.detection import convert_measurements
from sonar_tracking.core.tracking.config import TrackerConfig
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY
from sonar_tracking.studies.esc_study import resolution_cell_area
from sonar_tracking.studies.metrics import evaluate_scan, gospa, gospa_assignment, paired_difference
from sonar_tracking.studies.montecarlo import Progress, RunPool, run_monte_carlo

__all__ = ['JipdaStudy', 'GEOMETRIES', 'METHODS', 'METRICS', 'simulate', 'run_once', 'summarise', 'run_study',
           'format_table']

GEOMETRIES = ('crossing', 'parallel')
METHODS = ('ipda', 'jipda')
#: Per-run metrics, in table order.
METRICS = ('gospa', 'missed', 'false', 'swaps', 'coalescence', 'cttr')


@dataclass(frozen=True)
class JipdaStudy:
    """One geometry of the study and its simulation and tracker settings."""

    geometry: str = 'crossing'
    scans: int = 100
    speed: float = 5.0                       # [m/s]
    range_m: float = 2500.0                  # window centre's range from the sonar
    half_width: float = 300.0                # window: centre +/- this [m]
    p_detect: float = 0.9
    clutter_density: float = 5e-5            # [1/m^2]: 18 clutter detections per scan over the window
    sigma_r: float = 5.0                     # harbour sonar (ESC paper §5)
    sigma_theta_deg: float = 0.1
    crossing_deg: tuple[float, float] = (5.0, 20.0)
    parallel_cells: tuple[float, float] = (2.0, 4.0)
    gospa_c: float = 20.0                    # [m]
    max_cluster: int = 8
    unresolved: bool = False                 # targets within a cell give one merged detection

    def __post_init__(self) -> None:
        if self.geometry not in GEOMETRIES:
            raise ValueError(f'geometry {self.geometry!r} is not one of {GEOMETRIES}')
        if self.scans < 2:
            raise ValueError(f'scans = {self.scans} must be >= 2')

    @property
    def cell(self) -> float:
        """Side of the resolution cell at the window centre, ``sqrt(V_rc)`` [m]."""
        return math.sqrt(resolution_cell_area(self.sigma_r, self.range_m * math.radians(self.sigma_theta_deg)))

    @property
    def centre(self) -> np.ndarray:
        return np.array([HARBOUR_SONAR_XY[0] + self.range_m, HARBOUR_SONAR_XY[1]])


def _truth(study: JipdaStudy, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """``(scans, 2, 4)`` target states ``[x, y, vx, vy]`` and the geometry's parameter (deg or cells)."""
    heading = rng.uniform(0.0, 2 * math.pi)
    t = np.arange(study.scans) - (study.scans - 1) / 2.0          # 0 at the middle scan
    if study.geometry == 'crossing':
        param = rng.uniform(*study.crossing_deg)
        heads = heading + np.radians([param / 2.0, -param / 2.0])
        offsets = np.zeros((2, 2))
    else:
        param = rng.uniform(*study.parallel_cells)
        heads = np.array([heading, heading])
        normal = np.array([-math.sin(heading), math.cos(heading)])
        offsets = np.outer([0.5, -0.5], normal) * param * study.cell
    vel = study.speed * np.stack((np.cos(heads), np.sin(heads)), axis=1)         # (2, 2)
    pos = study.centre + offsets[None] + t[:, None, None] * vel[None]           # (scans, 2, 2)
    return np.concatenate((pos, np.broadcast_to(vel, pos.shape)), axis=2), float(param)


def _polar(study: JipdaStudy, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = xy - np.asarray(HARBOUR_SONAR_XY)
    return np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])


def simulate(study: JipdaStudy, rng: np.random.Generator) -> tuple[np.ndarray, list, float]:
    """Truth ``(scans, 2, 4)``, the detections ``[(z (N, 2), R (N, 2, 2))]`` per scan, and the geometry's
    parameter (crossing angle [deg] or separation [cells])."""
    truth, param = _truth(study, rng)
    sr, st = study.sigma_r, math.radians(study.sigma_theta_deg)
    area = (2 * study.half_width) ** 2
    scans = []
    for k in range(study.scans):
        seen = truth[k, rng.random(2) < study.p_detect, :2]
        if study.unresolved and len(seen) == 2 and np.hypot(*(seen[0] - seen[1])) < study.cell:
            seen = seen.mean(axis=0, keepdims=True)
        r, b = _polar(study, seen)
        r, b = r + rng.normal(0.0, sr, len(r)), b + rng.normal(0.0, st, len(b))
        clutter = study.centre + rng.uniform(-study.half_width, study.half_width,
                                             (rng.poisson(study.clutter_density * area), 2))
        rc, bc = _polar(study, clutter)
        z, R = convert_measurements(np.concatenate((r, rc)), np.concatenate((b, bc)), sr, st,
                                    pose=(*HARBOUR_SONAR_XY, 0.0))
        scans.append((z, R))
    return truth, scans, param


def _tracker(study: JipdaStudy, method: str) -> ImmIpdaTracker:
    return ImmIpdaTracker(TrackerConfig.from_flat({
        'detection.probability': study.p_detect, 'clutter.source': 'constant',
        'clutter.density': study.clutter_density, 'association.method': method,
        'association.max_cluster': study.max_cluster}))


def _score(study: JipdaStudy, truth: np.ndarray, outputs: list[np.ndarray], P0: np.ndarray) -> dict:
    """The per-run metrics of one method (module docstring)."""
    c, cell = study.gospa_c, study.cell
    gos, missed, false, cttr = [], [], [], []
    swaps, apart, coalesced = 0, 0, 0
    last = [0, 0]                                   # track id last assigned to each target (0: none yet)
    for k, tracks in enumerate(outputs):
        conf = tracks[tracks['confirmed'] != 0]
        est = np.column_stack((conf['x'], conf['y'])) if len(conf) else np.zeros((0, 2))
        pos = truth[k, :, :2]
        g = gospa(pos, est, c)
        gos.append(g.distance)
        missed.append(g.missed)
        false.append(g.false)
        cttr.append(evaluate_scan(truth[k], tracks, P0).has_ctt.mean())
        if np.hypot(*(pos[0] - pos[1])) <= cell:
            continue                                # too close for labels to mean anything
        apart += 1
        coalesced += _coalesced(pos, est, c, cell)
        rows, cols = gospa_assignment(pos, est, c)
        before = list(last)
        for j, col in zip(rows, cols):
            tid = int(conf['track_id'][col])
            if tid == before[1 - j] and tid != before[j]:
                swaps += 1
            last[j] = tid
    return {'gospa': float(np.mean(gos)), 'missed': float(np.mean(missed)), 'false': float(np.mean(false)),
            'swaps': float(swaps), 'coalescence': coalesced / apart if apart else math.nan,
            'cttr': float(np.mean(cttr))}


def _coalesced(pos: np.ndarray, est: np.ndarray, c: float, cell: float) -> bool:
    """Both targets' nearest confirmed track is the same one, or two confirmed tracks near the targets
    lie within half a cell of each other."""
    if len(est) == 0:
        return False
    d = np.hypot(est[:, None, 0] - pos[None, :, 0], est[:, None, 1] - pos[None, :, 1])     # (tracks, 2)
    nearest = d.argmin(axis=0)
    if nearest[0] == nearest[1] and d[nearest[0], 0] < c and d[nearest[1], 1] < c:
        return True
    near = est[d.min(axis=1) < c]
    if len(near) < 2:
        return False
    gap = np.hypot(near[:, None, 0] - near[None, :, 0], near[:, None, 1] - near[None, :, 1])
    return bool((gap[np.triu_indices(len(near), 1)] < 0.5 * cell).any())


def run_once(study: JipdaStudy, seed: np.random.SeedSequence) -> dict:
    """One run: simulate once, track the same detections with both associations, score each."""
    rng = np.random.default_rng(seed)
    truth, scans, param = simulate(study, rng)
    r0, b0 = _polar(study, study.centre[None])
    _, R0 = convert_measurements(r0, b0, study.sigma_r, math.radians(study.sigma_theta_deg))
    out = {'parameter': param}
    for method in METHODS:
        trk = _tracker(study, method)
        P0 = trk.initial_covariance(R0[0])
        outputs = [trk.step(float(k), z, R).copy() for k, (z, R) in enumerate(scans)]
        out[method] = _score(study, truth, outputs, P0)
    return out


def summarise(runs: list[dict]) -> dict:
    """Per method the mean of every metric, and per metric the paired difference JIPDA - IPDA."""
    out = {'runs': len(runs), 'means': {}, 'jipda_minus_ipda': {}}
    for m in METHODS:
        out['means'][m] = {k: _mean([r[m][k] for r in runs]) for k in METRICS}
    for k in METRICS:
        out['jipda_minus_ipda'][k] = paired_difference(np.array([r['jipda'][k] for r in runs]),
                                                       np.array([r['ipda'][k] for r in runs]))
    out['runs_with_swaps'] = {m: float(np.mean([r[m]['swaps'] > 0 for r in runs])) for m in METHODS}
    return out


def _mean(values: list[float]) -> float | None:
    """Mean of the finite values (a run without a scored scan has NaN coalescence); None if none."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else None


def run_study(runs: int, seed: int, pool: RunPool | None = None, scans: int | None = None,
              geometries: tuple[str, ...] = GEOMETRIES, progress: bool | None = None, unresolved: bool = False
              ) -> dict:
    """Every geometry, ``runs`` runs each seeded ``seed``; the JSON-ready result (per-run figures too)."""
    out = {'runs': runs, 'seed': seed, 'unresolved': unresolved, 'geometries': []}
    for g in geometries:
        study = JipdaStudy(geometry=g, unresolved=unresolved)
        if scans is not None:
            study = JipdaStudy(geometry=g, scans=scans, unresolved=unresolved)
        results = run_monte_carlo(run_once, study, runs, seed, pool=pool, progress=Progress(g, runs, enabled=progress))
        out['geometries'].append({'geometry': g, 'study': _describe(study), **summarise(results),
                                  'per_run': results})
    return out


def _describe(study: JipdaStudy) -> dict:
    d = {k: getattr(study, k) for k in study.__dataclass_fields__}
    d['cell_m'] = study.cell
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


def format_table(result: dict) -> str:
    """The docs/results table (markdown) of :func:`run_study`'s result."""
    lines = [f'{result["runs"]} runs per geometry, seed {result["seed"]}; means per run; JIPDA - IPDA: paired '
             'per-run difference, 95 % interval', '',
             '| geometry | metric | IPDA | JIPDA | JIPDA − IPDA |', '|---|---|---|---|---|']
    for g in result['geometries']:
        for k in METRICS:
            p = g['jipda_minus_ipda'][k]
            diff = 'n/a' if p['difference'] is None else (f'{p["difference"]:+.4f}' + (
                '' if p['ci95'] is None else f' ± {p["ci95"]:.4f}'))
            a, b = (g['means'][m][k] for m in METHODS)
            lines.append(f'| {g["geometry"]} | {k} | {_fmt(a)} | {_fmt(b)} | {diff} |')
        lines.append(f'| {g["geometry"]} | runs with a swap | {g["runs_with_swaps"]["ipda"]:.3f} | '
                     f'{g["runs_with_swaps"]["jipda"]:.3f} | |')
    return '\n'.join(lines)


def _fmt(v: float | None) -> str:
    return 'n/a' if v is None else f'{v:.4f}'

"""IMM-JIPDA against independent IMM-IPDA on two close targets, in and out of the trackers' model.

A measurement-level simulation (no sectors, no detector): the harbour sonar of the ESC scenarios
(at :data:`~sonar_tracking.sim.presets.HARBOUR_SONAR_XY`, heading 0, range std ``sigma_r`` 5 m,
bearing std ``sigma_theta`` 0.1 deg) looks at a polar window centred 2500 m away
(:meth:`JipdaStudy.window`: ranges ``range_m +/- half_width``, bearings of an arc ``2 half_width``
long at ``range_m``), one scan per second. Each target is detected with probability ``p_detect``;
its detection is the true range and bearing plus Gaussian noise, converted to x, y with the
covariance of eq. (10) (:func:`~sonar_tracking.core.detection.convert_measurements`). Clutter is
Poisson with density ``clutter_density`` per m^2, uniform over the window, each clutter detection
with the covariance of its own range and bearing.

Geometries (random per run):

* ``crossing``: two targets at the same speed whose tracks cross at the window centre at an angle
  uniform in ``crossing_deg`` (5-20 deg), at the middle scan; the pair heads in a uniform direction;
* ``parallel``: two targets on parallel courses ``parallel_cells`` (2-4) resolution cells apart
  (the cell side ``sqrt(V_rc)``, ``V_rc = 12 sigma_r sigma_theta r``, 16.2 m at 2500 m), passing the
  window centre at the middle scan.

Where the trackers' model is wrong (:data:`CONDITIONS`; ``matched`` is the model itself):

* ``scmde``: the trackers do not know the clutter density; each detection's is estimated by SCMDE
  (order 6, edge-corrected in the window, :func:`~sonar_tracking.core.detection.scmde.scmde`), as
  the detector does (``clutter.source: detection``);
* ``pd_high`` / ``pd_low``: the trackers' P_D is wrong by +0.1 (true 0.8, assumed 0.9) or by -0.1
  (true 0.9, assumed 0.8);
* ``manoeuvre``: every target turns all run long at a rate uniform in ``turn_deg`` (1-3 deg/s, the
  IMM's turn modes are 3 deg/s) in a random direction per target (``parallel``: both the same
  turn, as a formation), still crossing or passing the centre at the middle scan;
* ``unresolved``: two targets both detected within one resolution cell of each other give one
  detection, at the centroid of their positions weighted by their echoes' strengths (independent
  exponential amplitudes, Swerling I), which neither tracker models;
* ``all``: every mismatch above at once (P_D +0.1).

Both trackers (``association.method`` ``ipda`` and ``jipda``, otherwise identical: three IMM modes,
the node's defaults) track the SAME detections of each run; each builds with its own confirmation
threshold T_c (``confirm_by_method``) and every run records the T_c its tracker holds, read from its
configuration. A run is a pure function of the study and its seed (all randomness from one
``numpy.random.Generator``).

Per run and method (confirmed tracks):

* ``gospa``: mean over scans of GOSPA (:data:`GOSPA`: c = 20 m, p = 2, alpha = 2) between the true
  positions and the confirmed tracks' positions, and its parts (``missed`` targets and ``false``
  tracks per scan);
* ``swaps``: on the scans where the targets are more than one cell apart, the times a target's
  assigned confirmed track (the GOSPA assignment within ``c``) is the track the other target was
  last assigned on such a scan (while they are closer, labels are ambiguous and not scored);
* ``coalescence``: fraction of the scans with the targets more than one cell apart in which both
  targets' nearest confirmed tracks are the same track, or two confirmed tracks within ``c`` of a
  target lie within half a cell of each other (NaN for a run with no such scan);
* ``cttr``: fraction of (scan, target) with a confirmed true track (eqs. 47-48, ``P_{0|0}`` of a
  track started at the window centre).

With ``sweep_grid`` the trackers confirm at the grid's lowest T_c and each run also records, per T_c
of the grid, the mean GOSPA of the tracks whose existence has exceeded it (:func:`run_once`): the
screen of the calibration (:mod:`.jipda_table`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.detection import convert_measurements
from sonar_tracking.core.detection.scmde import PolarWindow, scmde
from sonar_tracking.core.tracking.config import TrackerConfig
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY
from sonar_tracking.studies.esc_study import resolution_cell_area
from sonar_tracking.studies.evidence import GospaSpec
from sonar_tracking.studies.metrics import evaluate_scan, gospa_assignment

__all__ = ['JipdaStudy', 'GEOMETRIES', 'METHODS', 'METRICS', 'CONDITIONS', 'CELLS', 'GOSPA', 'for_condition',
           'simulate', 'run_once']

GEOMETRIES = ('crossing', 'parallel')
METHODS = ('ipda', 'jipda')
#: Per-run metrics, in table order.
METRICS = ('gospa', 'missed', 'false', 'swaps', 'coalescence', 'cttr')
#: GOSPA of the JIPDA study.
GOSPA = GospaSpec(c=20.0, p=2.0, alpha=2.0)

#: Study settings of each condition (module docstring).
CONDITIONS: dict[str, dict] = {
    'matched': {},
    'scmde': {'clutter_model': 'scmde'},
    'pd_high': {'p_detect': 0.8, 'assumed_p_detect': 0.9},
    'pd_low': {'p_detect': 0.9, 'assumed_p_detect': 0.8},
    'manoeuvre': {'turn_deg': (1.0, 3.0)},
    'unresolved': {'unresolved': True},
    'all': {'clutter_model': 'scmde', 'p_detect': 0.8, 'assumed_p_detect': 0.9, 'turn_deg': (1.0, 3.0),
            'unresolved': True},
}

#: (geometry, condition) cells of the table: parallel targets are never within a cell, so
#: ``unresolved`` there is ``matched``.
CELLS = tuple((g, c) for g in GEOMETRIES for c in CONDITIONS if not (g == 'parallel' and c == 'unresolved'))


@dataclass(frozen=True)
class JipdaStudy:
    """One geometry and condition of the study: the simulation and the trackers' settings."""

    geometry: str = 'crossing'
    scans: int = 100
    speed: float = 5.0                       # [m/s]
    range_m: float = 2500.0                  # window centre's range from the sonar
    half_width: float = 300.0                # window: ranges centre +/- this, an arc of twice this [m]
    p_detect: float = 0.9                    # the targets' true P_D
    assumed_p_detect: float | None = None    # the trackers' P_D (None: the true one)
    clutter_density: float = 5e-5            # [1/m^2]: 18 clutter detections per scan over the window
    clutter_model: str = 'constant'          # the trackers': 'constant' (the true density) or 'scmde'
    sigma_r: float = 5.0                     # harbour sonar (ESC paper §5)
    sigma_theta_deg: float = 0.1
    crossing_deg: tuple[float, float] = (5.0, 20.0)
    parallel_cells: tuple[float, float] = (2.0, 4.0)
    turn_deg: tuple[float, float] = (0.0, 0.0)   # turn-rate magnitude range [deg/s]; 0: straight
    unresolved: bool = False                 # targets within a cell give one merged detection
    max_cluster: int = 8
    scmde_order: int = 6
    confirm_by_method: tuple[tuple[str, float], ...] = ()   # (method, T_c) run inside the run
    sweep_grid: tuple[float, ...] = ()       # record GOSPA per T_c of this grid (trackers confirm at its lowest)

    def __post_init__(self) -> None:
        if self.geometry not in GEOMETRIES:
            raise ValueError(f'geometry {self.geometry!r} is not one of {GEOMETRIES}')
        if self.scans < 2:
            raise ValueError(f'scans = {self.scans} must be >= 2')
        if self.clutter_model not in ('constant', 'scmde'):
            raise ValueError(f'clutter_model {self.clutter_model!r} is not constant or scmde')
        if list(self.sweep_grid) != sorted(self.sweep_grid):
            raise ValueError('sweep_grid must be ascending')

    @property
    def cell(self) -> float:
        """Side of the resolution cell at the window centre, ``sqrt(V_rc)`` [m]."""
        return math.sqrt(resolution_cell_area(self.sigma_r, self.range_m * math.radians(self.sigma_theta_deg)))

    @property
    def centre(self) -> np.ndarray:
        return np.array([HARBOUR_SONAR_XY[0] + self.range_m, HARBOUR_SONAR_XY[1]])

    @property
    def window(self) -> PolarWindow:
        """The clutter window in the sonar's frame (heading 0)."""
        half = self.half_width / self.range_m
        return PolarWindow(self.range_m - self.half_width, self.range_m + self.half_width, -half, half)

    @property
    def tracker_p_detect(self) -> float:
        return self.p_detect if self.assumed_p_detect is None else self.assumed_p_detect

    def confirm_for(self, method: str) -> float | None:
        """The T_c ``method``'s tracker is built with (None: the tracker's default)."""
        own = dict(self.confirm_by_method)
        if method in own:
            return float(own[method])
        return float(self.sweep_grid[0]) if self.sweep_grid else None


def for_condition(condition: str, geometry: str, **overrides) -> JipdaStudy:
    """The study of one cell: :data:`CONDITIONS` ``condition`` on ``geometry`` (and ``overrides``)."""
    if condition not in CONDITIONS:
        raise ValueError(f'condition {condition!r} is not one of {tuple(CONDITIONS)}')
    return JipdaStudy(geometry=geometry, **{**CONDITIONS[condition], **overrides})


def _paths(t: np.ndarray, ref: np.ndarray, heading: float, omega: float, speed: float,
           offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities ``(len(t), 2)`` of a point ``offset`` from a reference point that is at
    ``ref`` at ``t = 0`` heading ``heading`` and turns at ``omega`` [rad/s] (the offset turns with it)."""
    h = heading + omega * t
    if omega == 0.0:
        p = ref + speed * np.outer(t, [math.cos(heading), math.sin(heading)])
    else:
        p = ref + (speed / omega) * np.column_stack((np.sin(h) - math.sin(heading), math.cos(heading) - np.cos(h)))
    c, s = np.cos(omega * t), np.sin(omega * t)
    off = np.column_stack((c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]))
    v = speed * np.column_stack((np.cos(h), np.sin(h))) + omega * np.column_stack((-off[:, 1], off[:, 0]))
    return p + off, v


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
    omegas = np.zeros(2)
    if study.turn_deg[1] > 0:
        rates = np.radians(rng.uniform(*study.turn_deg, 2)) * rng.choice((-1.0, 1.0), 2)
        omegas = rates if study.geometry == 'crossing' else np.full(2, rates[0])
    out = np.empty((study.scans, 2, 4))
    for i in range(2):
        p, v = _paths(t, study.centre, float(heads[i]), float(omegas[i]), study.speed, offsets[i])
        out[:, i, :2], out[:, i, 2:] = p, v
    return out, float(param)


def _polar(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = xy - np.asarray(HARBOUR_SONAR_XY)
    return np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])


def simulate(study: JipdaStudy, rng: np.random.Generator) -> tuple[np.ndarray, list, float]:
    """Truth ``(scans, 2, 4)``, the detections ``[(z (N, 2), R (N, 2, 2), rho (N,))]`` per scan (``rho``
    the clutter density the trackers are given), and the geometry's parameter (crossing angle [deg]
    or separation [cells])."""
    truth, param = _truth(study, rng)
    sr, st = study.sigma_r, math.radians(study.sigma_theta_deg)
    win = study.window
    scans = []
    for k in range(study.scans):
        seen = truth[k, rng.random(2) < study.p_detect, :2]
        if study.unresolved and len(seen) == 2 and np.hypot(*(seen[0] - seen[1])) < study.cell:
            w = rng.exponential(1.0, 2)
            seen = (w @ seen / w.sum())[None, :]
        r, b = _polar(seen)
        r, b = r + rng.normal(0.0, sr, len(r)), b + rng.normal(0.0, st, len(b))
        n = rng.poisson(study.clutter_density * win.area)
        rc = np.sqrt(rng.uniform(win.r_min ** 2, win.r_max ** 2, n))
        bc = rng.uniform(win.b_min, win.b_max, n)
        rr, bb = np.concatenate((r, rc)), np.concatenate((b, bc))
        z, R = convert_measurements(rr, bb, sr, st, pose=(*HARBOUR_SONAR_XY, 0.0))
        if study.clutter_model == 'scmde':
            rho = scmde(np.column_stack((rr * np.cos(bb), rr * np.sin(bb))), study.scmde_order, win)
        else:
            rho = np.full(len(z), study.clutter_density)
        scans.append((z, R, rho))
    return truth, scans, param


def _tracker(study: JipdaStudy, method: str) -> ImmIpdaTracker:
    flat = {'detection.probability': study.tracker_p_detect, 'association.method': method,
            'association.max_cluster': study.max_cluster,
            'clutter.source': 'detection' if study.clutter_model == 'scmde' else 'constant',
            'clutter.density': study.clutter_density}
    confirm = study.confirm_for(method)
    if confirm is not None:
        flat['existence.confirm'] = confirm
    return ImmIpdaTracker(TrackerConfig.from_flat(flat))


def _score(study: JipdaStudy, truth: np.ndarray, outputs: list[np.ndarray], P0: np.ndarray) -> dict:
    """The per-run metrics of one method (module docstring)."""
    c, cell = GOSPA.c, study.cell
    gos, missed, false, cttr = [], [], [], []
    swaps, apart, coalesced = 0, 0, 0
    last = [0, 0]                                   # track id last assigned to each target (0: none yet)
    for k, tracks in enumerate(outputs):
        conf = tracks[tracks['confirmed'] != 0]
        est = np.column_stack((conf['x'], conf['y'])) if len(conf) else np.zeros((0, 2))
        pos = truth[k, :, :2]
        g = GOSPA(pos, est)
        gos.append(g.distance)
        missed.append(g.missed)
        false.append(g.false)
        cttr.append(evaluate_scan(truth[k], tracks, P0).has_ctt.mean())
        if np.hypot(*(pos[0] - pos[1])) <= cell:
            continue                                # too close for labels to mean anything
        apart += 1
        coalesced += _coalesced(pos, est, c, cell)
        rows, cols = gospa_assignment(pos, est, c, GOSPA.p)
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


def _swept_gospa(study: JipdaStudy, truth: np.ndarray, outputs: list[np.ndarray]) -> list[float]:
    """Mean GOSPA over scans for each T_c of ``sweep_grid``: a track counts as confirmed at T once its
    existence has exceeded T (confirmation is kept, as in the tracker)."""
    grid = np.asarray(study.sweep_grid)
    best: dict[int, float] = {}
    total = np.zeros(len(grid))
    for k, tracks in enumerate(outputs):
        ex = np.empty(len(tracks))
        for i, (tid, e) in enumerate(zip(tracks['track_id'].tolist(), tracks['existence'].tolist())):
            best[tid] = ex[i] = max(best.get(tid, 0.0), e)
        xy = np.column_stack((tracks['x'], tracks['y']))
        for j, T in enumerate(grid):
            total[j] += GOSPA(truth[k, :, :2], xy[ex > T]).distance
    return (total / len(outputs)).tolist()


def run_once(study: JipdaStudy, seed: np.random.SeedSequence) -> dict:
    """One run: simulate once, track the same detections with both associations, score each; per
    method also ``confirm``, the T_c its tracker holds, and with ``sweep_grid`` ``swept_gospa``."""
    rng = np.random.default_rng(seed)
    truth, scans, param = simulate(study, rng)
    r0, b0 = _polar(study.centre[None])
    _, R0 = convert_measurements(r0, b0, study.sigma_r, math.radians(study.sigma_theta_deg))
    out: dict = {'parameter': param}
    for method in METHODS:
        trk = _tracker(study, method)
        P0 = trk.initial_covariance(R0[0])
        outputs = [trk.step(float(k), z, R, rho).copy() for k, (z, R, rho) in enumerate(scans)]
        out[method] = {**_score(study, truth, outputs, P0), 'confirm': float(trk.config.existence.confirm)}
        if study.sweep_grid:
            out[method]['swept_gospa'] = _swept_gospa(study, truth, outputs)
    return out

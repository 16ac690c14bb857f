"""IMM-IPDA tracker speed (issues 5, 19, 24), against Stone Soup 1.9.1 on identical detections.

Scenario: K constant-velocity targets (``tK`` cases; one in the ``cN`` cases) seen with P_D 0.9
and Poisson clutter uniform over 1000 m x 1000 m, N clutter detections per scan on average (20 in
the ``tK`` cases), one scan per second, measurement covariance diag(25, 25) m^2; the same seeded
detections for every tracker. Each repeat times one scan (``tracker.step``, including gating,
update, initiation and track management) after a warm-up that lets the track population settle;
the table gives the median over scans. ``growth`` is the exponent of time against size from the
previous size of the same series (log ratio of medians), when both ran.

* ``tracking.imm_ipda.cN`` / ``tK``: ours, 3 modes (CV, CTR left and right), default settings
  (the node's: initiation budget and caps) with the true clutter density.
* ``tracking.imm_ipda.flood20000``: 20,000 uniform detections per scan over 1 km^2 for 100 scans
  in a fresh process; every scan is a sample, and ``peak_rss_mb`` is that process's peak resident
  memory (``VmHWM`` on Linux, else ``resource.getrusage``, whose figure can be the forking
  parent's), Python, numpy and the tracker included.
* ``tracking.stonesoup.*``: Stone Soup 1.9.1 ``MultiTargetMixtureTracker`` with ``KDTreePDA``
  (the detections of a scan in a k-d tree; a track's PDA hypotheses only for those within
  ``KD_RADIUS`` of its predicted position: 40 m, 8 sigma of R0, wider than a settled track's
  99 % gate);
  ``PDAHypothesiser``: same P_D, P_G 0.99, clutter density), one CV model with the same process
  noise, ``MultiMeasurementInitiator`` (2 points, GNN with a 3-sigma Mahalanobis gate, prior
  velocity variance as ours), tracks deleted after 3 scans without an update or when their
  position variance exceeds ours (30 m std per axis).
* ``tracking.imm_jipda.pairsK`` / ``tracking.imm_ipda.pairsK`` / ``tracking.stonesoup_jpda.pairsK``:
  K targets in pairs 15 m apart (their gates overlap) + 20 clutter: ours with
  ``association.method: jipda`` (ratio against Stone Soup's JPDA), ours with ``ipda`` (ratio: the
  JIPDA time over the IPDA time) and Stone Soup 1.9.1 with ``JPDA`` (same ``PDAHypothesiser``, no
  k-d tree) in place of ``KDTreePDA``, otherwise as above. Stone Soup is a bench extra
  (``pip install -r requirements-bench.txt``); without it these cases say so in the table and
  report no time.
"""
from __future__ import annotations

import gc
import json
import math
import subprocess
import sys
import time

import numpy as np

from sonar_tracking.cli.bench import Case, Result, register

CLUTTER = (0, 20, 100, 1000, 10000)
TARGETS = (1, 10, 50, 200)
# Stone Soup beside every scaling row it can finish: (tag, clutter, targets, warm-up scans, repeats).
# Where its cost allows, it is timed on the scans ours is (after WARMUP): its scans 10-25 at 10
# targets cost 1.2x its settled ones. Its initiator associates every unused detection with every
# holding track (GNN), so a scan grows with clutter^2: 2-3 s at 100 clutter, 37-77 s at 1,000; those
# rows warm up a few scans only (its scans still grow then: in its favour), and 10,000 (hours) is not run.
WARMUP = 40
STONESOUP = (('c0', 0, 1, WARMUP, 30), ('c20', 20, 1, WARMUP, 30), ('c100', 100, 1, 4, 4), ('c1000', 1000, 1, 1, 1),
             ('t10', 20, 10, WARMUP, 15), ('t50', 20, 50, 4, 6), ('t200', 20, 200, 2, 3))
_SS_TAGS = {tag for tag, *_ in STONESOUP}
PAIRS = (2, 10)                # JIPDA cases: targets in pairs
PAIR_GAP = 15.0                # [m] between the two targets of a pair (3 sigma of R0: their gates overlap)
FLOOD = 20000
FLOOD_SCANS = 100
P_D = 0.9
HALF = 500.0
R0 = np.diag([25.0, 25.0])
Q = 0.01                       # acceleration PSD: our default noise_cv
SPEED_MAX = 15.0
KD_RADIUS = 40.0               # [m] Stone Soup's k-d tree search radius (8 sigma of R0)
STONESOUP_VERSION = '1.9.1'
MISSING = f'SKIPPED: stonesoup not installed (pip install -r requirements-bench.txt for stonesoup=={STONESOUP_VERSION})'


def scans(n_clutter: int, n_scans: int, seed: int = 7, n_targets: int = 1, pair_gap: float = 0.0
          ) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
    """``(t, z, R, rho)`` per scan: the targets (each with probability P_D) and Poisson clutter.

    Targets start on a grid over the square and move at 4.5 m/s in directions spread over the
    circle; every 200 scans they start again. With ``pair_gap`` > 0 they go in pairs instead: the
    grid holds ``n_targets / 2`` pairs, the two of a pair on parallel courses ``pair_gap`` m apart.
    ``R`` is a read-only broadcast of ``R0``.
    """
    rng = np.random.default_rng(seed)
    rho = max(n_clutter, 1) / (2 * HALF) ** 2
    n_groups = n_targets // 2 if pair_gap > 0 else n_targets
    side = math.ceil(math.sqrt(n_groups))
    grid = (np.arange(side) + 0.5) / side * 1.6 * HALF - 0.8 * HALF
    start = np.stack(np.meshgrid(grid, grid), -1).reshape(-1, 2)[:n_groups]
    if n_groups == 1:
        start = np.array([[-400.0, -200.0]])
    angle = np.arctan2(2.0, 4.0) + 2 * math.pi * np.arange(n_groups) / n_groups
    vel = math.hypot(4.0, 2.0) * np.stack((np.cos(angle), np.sin(angle)), -1)
    if pair_gap > 0:
        normal = np.stack((-np.sin(angle), np.cos(angle)), -1) * (pair_gap / 2.0)
        start = np.concatenate((start + normal, start - normal))
        vel = np.concatenate((vel, vel))
    out = []
    for k in range(n_scans):
        clutter = rng.uniform(-HALF, HALF, (rng.poisson(n_clutter), 2))
        seen = rng.random(n_targets) < P_D
        hits = start[seen] + vel[seen] * (k % 200) + rng.multivariate_normal([0.0, 0.0], R0, int(seen.sum()))
        z = np.concatenate((hits, clutter))
        out.append((float(k), z, np.broadcast_to(R0, (len(z), 2, 2)), np.full(len(z), rho)))
    return out


class _Stepper:
    """Steps a tracker through pre-built scans, one per call, timing only the tracker's work."""

    def __init__(self, make_tracker, step, data, warmup: int) -> None:
        self.make_tracker, self.step, self.data, self.warmup = make_tracker, step, data, warmup
        self.tracks: list[int] = []
        self._start()

    def _start(self) -> None:
        self.tracker = self.make_tracker()
        self.i = 0
        for _ in range(self.warmup):
            self._advance()

    def _advance(self) -> int:
        n = self.step(self.tracker, self.data[self.i])
        self.i += 1
        return n

    def __call__(self) -> float:
        if self.i >= len(self.data):
            self._start()              # untimed: a fresh tracker warmed up again
        enabled = gc.isenabled()
        gc.disable()
        try:
            t0 = time.perf_counter()
            n = self._advance()
            elapsed = time.perf_counter() - t0
        finally:
            if enabled:
                gc.enable()
        self.tracks.append(n)
        return elapsed


_STEPPERS: dict[str, _Stepper] = {}


def _ours(n_clutter: int, name: str, n_targets: int = 1, n_scans: int = 400, association: str = 'ipda',
          pair_gap: float = 0.0):
    def make():
        from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig
        cfg = TrackerConfig.from_flat({'detection.probability': P_D, 'clutter.source': 'detection',
                                       'imm.noise_cv': Q, 'init.speed_max': SPEED_MAX,
                                       'association.method': association})

        def step(tracker, scan):
            tracker.step(*scan)
            return tracker.n_tracks
        stepper = _Stepper(lambda: ImmIpdaTracker(cfg), step,
                           scans(n_clutter, n_scans, n_targets=n_targets, pair_gap=pair_gap), warmup=WARMUP)
        _STEPPERS[name] = stepper
        return stepper
    return make


def flood_child(n: int, n_scans: int) -> None:
    """Run in a fresh process: ``n`` uniform detections per scan for ``n_scans`` scans; print JSON
    with the seconds per scan and the process's peak RSS [MB]."""
    import resource

    from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig
    rng = np.random.default_rng(19)
    tracker = ImmIpdaTracker(TrackerConfig.from_flat({'clutter.source': 'detection'}))
    rho = np.full(n, n / (2 * HALF) ** 2)
    R = np.broadcast_to(R0, (n, 2, 2))
    seconds, pairs, tracks = [], [], []
    for k in range(n_scans):
        z = rng.uniform(-HALF, HALF, (n, 2))
        t0 = time.perf_counter()
        tracker.step(float(k), z, R, rho)
        seconds.append(time.perf_counter() - t0)
        pairs.append(tracker.report.n_pairs)
        tracks.append(tracker.n_tracks)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0       # kB on Linux
    try:
        # ru_maxrss survives exec, so it can be the forking parent's; VmHWM belongs to this process image.
        with open('/proc/self/status') as f:
            rss = next(float(line.split()[1]) for line in f if line.startswith('VmHWM:')) / 1024.0
    except (OSError, StopIteration, ValueError):
        pass
    print(json.dumps({'seconds': seconds, 'peak_rss_mb': rss, 'max_pairs': max(pairs), 'max_tracks': max(tracks)}))


_FLOOD: dict = {}


def _flood(n: int, n_scans: int):
    def make():
        def run() -> list[float]:
            code = f'from {__name__} import flood_child; flood_child({n}, {n_scans})'
            done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
            _FLOOD.update(json.loads(done.stdout.strip().splitlines()[-1]))
            return _FLOOD['seconds']
        return run
    return make


def _flood_derived(r: Result) -> dict:
    return {'peak_rss_mb': _FLOOD.get('peak_rss_mb', math.nan), 'max_pairs': _FLOOD.get('max_pairs', math.nan),
            'max_tracks': _FLOOD.get('max_tracks', math.nan), 'max_ms': r.max_s * 1e3}


def _stonesoup(n_clutter: int, name: str, warmup: int, n_targets: int = 1, joint: bool = False,
               pair_gap: float = 0.0):
    def make():
        try:
            import stonesoup
        except ImportError:
            print(f'  {name}: {MISSING}', file=sys.stderr)
            return lambda: math.nan
        if stonesoup.__version__ != STONESOUP_VERSION:
            print(f'  {name}: stonesoup {stonesoup.__version__} installed, the comparison was set up for '
                  f'{STONESOUP_VERSION}', file=sys.stderr)
        data = _stonesoup_scans(n_clutter, warmup + 60, n_targets, pair_gap)
        rho = max(n_clutter, 1) / (2 * HALF) ** 2        # as ours (scans())

        def step(tracker, scan):
            return len(next(tracker)[1])
        stepper = _Stepper(lambda: _stonesoup_tracker(data, rho, joint), step, data, warmup=warmup)
        _STEPPERS[name] = stepper
        return stepper
    return make


def _stonesoup_scans(n_clutter: int, n_scans: int, n_targets: int = 1, pair_gap: float = 0.0):
    from datetime import datetime, timedelta

    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import Detection
    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R0)
    t0 = datetime(2025, 1, 1)
    out = []
    for t, z, _, _ in scans(n_clutter, n_scans, n_targets=n_targets, pair_gap=pair_gap):
        ts = t0 + timedelta(seconds=t)
        out.append((ts, {Detection(np.array([[a], [b]]), timestamp=ts, measurement_model=model) for a, b in z}))
    return out


def _stonesoup_tracker(data, rho, joint: bool = False):
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import JPDA
    from stonesoup.dataassociator.tree import KDTreePDA
    from stonesoup.deleter.error import CovarianceBasedDeleter
    from stonesoup.deleter.multi import CompositeDeleter
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R0)
    predictor = KalmanPredictor(CombinedLinearGaussianTransitionModel([ConstantVelocity(Q), ConstantVelocity(Q)]))
    updater = KalmanUpdater(model)

    def deleter():
        # mapping as a list: Stone Soup 1.9.1 indexes the diagonal with it.
        return CompositeDeleter([UpdateTimeStepsDeleter(time_steps_since_update=3),
                                 CovarianceBasedDeleter(covar_trace_thresh=2 * 30.0 ** 2, mapping=[0, 2])],
                                intersect=False)
    v = SPEED_MAX ** 2 / 3.0
    initiator = MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([0.0, v, 0.0, v])), measurement_model=model,
        deleter=deleter(), updater=updater, min_points=2,
        data_associator=GNNWith2DAssignment(DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3)))
    hypothesiser = PDAHypothesiser(predictor, updater, clutter_spatial_density=rho, prob_detect=P_D, prob_gate=0.99)
    tracker = MultiTargetMixtureTracker(
        initiator=initiator, deleter=deleter(), detector=iter(data), updater=updater,
        data_associator=JPDA(hypothesiser) if joint else KDTreePDA(hypothesiser, predictor, updater,
                                                                   max_distance=KD_RADIUS))
    return iter(tracker)


_MEDIANS: dict[str, float] = {}


def _derived(name: str, n_detections: float, previous: str | None = None, size_ratio: float = 1.0):
    def derived(r: Result) -> dict:
        stepper = _STEPPERS.get(name)
        if stepper is None or math.isnan(r.median_s):
            return {'note': MISSING}
        _MEDIANS[name] = r.median_s
        out = {'us_per_detection': r.median_s * 1e6 / max(n_detections, 1.0),
               'tracks': float(np.mean(stepper.tracks)) if stepper.tracks else math.nan}
        if previous in _MEDIANS:
            out['growth'] = math.log(r.median_s / _MEDIANS[previous]) / math.log(size_ratio)
        return out
    return derived


_prev, _prev_n = None, 1
for _n in CLUTTER:
    _name = f'tracking.imm_ipda.c{_n}'
    register(Case(
        name=_name, group='tracking', make=_ours(_n, _name, n_scans=400 if _n <= 1000 else 200), self_timed=True,
        repeats=150, compare_to=f'tracking.stonesoup.c{_n}' if f'c{_n}' in _SS_TAGS else None,
        limit_s={20: 0.35e-3, 10000: 0.1}.get(_n),
        derived=_derived(_name, _n + P_D, _prev if _prev and _n >= 1000 else None, _n / max(_prev_n, 1)
                         if _prev else 1.0),
        description=f'IMM-IPDA, 3 modes: one scan, 1 CV target (P_D 0.9) + {_n} clutter/scan over 1 km^2 (core)'))
    _prev, _prev_n = _name, _n

_prev, _prev_k = None, 1
for _k in TARGETS:
    _name = f'tracking.imm_ipda.t{_k}'
    register(Case(
        name=_name, group='tracking', make=_ours(20, _name, n_targets=_k), self_timed=True, repeats=150,
        compare_to=f'tracking.stonesoup.t{_k}' if f't{_k}' in _SS_TAGS else None, limit_s=3e-3 if _k == 200 else None,
        derived=_derived(_name, 20 + P_D * _k, _prev, _k / _prev_k if _prev else 1.0),
        description=f'IMM-IPDA, 3 modes: one scan, {_k} CV targets (P_D 0.9) + 20 clutter/scan over 1 km^2 (core)'))
    _prev, _prev_k = _name, _k

register(Case(
    name=f'tracking.imm_ipda.flood{FLOOD}', group='tracking', make=_flood(FLOOD, FLOOD_SCANS), self_timed=True,
    repeats=1, derived=_flood_derived,
    description=f'IMM-IPDA, default settings: {FLOOD} uniform detections/scan over 1 km^2 for {FLOOD_SCANS} scans, '
                'fresh process (time per scan; peak RSS of that process)'))

for _tag, _n, _k, _warm, _reps in STONESOUP:
    _name = f'tracking.stonesoup.{_tag}'
    register(Case(
        name=_name, group='tracking', make=_stonesoup(_n, _name, _warm, _k), self_timed=True, repeats=_reps,
        derived=_derived(_name, _n + P_D * _k),
        description=f'Stone Soup {STONESOUP_VERSION} MultiTargetMixtureTracker + KDTreePDA + '
                    f'MultiMeasurementInitiator, same detections ({_k} targets, {_n} clutter/scan)'))

for _k in PAIRS:
    _ipda, _jipda, _ss = (f'tracking.imm_ipda.pairs{_k}', f'tracking.imm_jipda.pairs{_k}',
                          f'tracking.stonesoup_jpda.pairs{_k}')
    register(Case(
        name=_jipda, group='tracking', make=_ours(20, _jipda, n_targets=_k, association='jipda', pair_gap=PAIR_GAP),
        self_timed=True, repeats=150, compare_to=_ss, derived=_derived(_jipda, 20 + P_D * _k),
        description=f'IMM-JIPDA, 3 modes: one scan, {_k} CV targets in pairs {PAIR_GAP:g} m apart (P_D 0.9) '
                    '+ 20 clutter/scan over 1 km^2 (core)'))
    register(Case(
        name=_ipda, group='tracking', make=_ours(20, _ipda, n_targets=_k, pair_gap=PAIR_GAP), self_timed=True,
        repeats=150, compare_to=_jipda, derived=_derived(_ipda, 20 + P_D * _k),
        description=f'IMM-IPDA, 3 modes: the same scans as {_jipda} (ratio: JIPDA time / IPDA time)'))
    register(Case(
        name=_ss, group='tracking', make=_stonesoup(20, _ss, 10, _k, joint=True, pair_gap=PAIR_GAP),
        self_timed=True, repeats=15, derived=_derived(_ss, 20 + P_D * _k),
        description=f'Stone Soup {STONESOUP_VERSION} MultiTargetMixtureTracker + JPDA + MultiMeasurementInitiator, '
                    f'same detections as {_jipda}'))

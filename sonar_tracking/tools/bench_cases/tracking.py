"""IMM-IPDA tracker speed and scaling (issues 5, 24), against Stone Soup 1.9.1 on identical detections.

Scenario: T constant-velocity targets seen with P_D 0.9 and Poisson clutter uniform over
1000 m x 1000 m, N clutter detections per scan on average, one scan per second, measurement
covariance diag(25, 25) m^2; the same seeded detections for every tracker. Each repeat times one
scan (``tracker.step``, including gating, update, initiation and track management) after a
warm-up that lets the track population settle; the table gives the median over scans.

* ``tracking.imm_ipda.tT``: ours, T targets + 20 clutter; ``tracking.imm_ipda.cN``: 1 target + N
  clutter. 3 modes (CV, CTR left and right), default settings with the true clutter density.
  ``growth`` is the exponent of time against the row's variable from the previous row of its
  series (``log(t_b / t_a) / log(x_b / x_a)``), when both ran.
* ``tracking.stonesoup.*``: Stone Soup 1.9.1 ``MultiTargetMixtureTracker`` with ``KDTreePDA``
  (``PDAHypothesiser``: same P_D, P_G 0.99, clutter density; detections within 40 m of the
  predicted measurement, the 99 % gate of a new track), one CV model with the same process
  noise, ``MultiMeasurementInitiator`` (2 points, KD-tree GNN with a 3-sigma Mahalanobis gate,
  prior velocity variance as ours), tracks deleted after 3 scans without an update or when their
  position variance exceeds ours (30 m std per axis). Stone Soup is a bench extra
  (``pip install -r requirements-bench.txt``); without it these cases say so in the table and
  report no time. It has no 10,000-clutter row (minutes per scan).
* ``tracking.imm_ipda.d20000``: 20,000 uniform detections per scan over 4 km x 4 km for 100
  scans, in a child process started with the allocator settings
  (:mod:`sonar_tracking.core.allocator`); time per scan and the child's peak RSS.
"""
from __future__ import annotations

import gc
import json
import math
import subprocess
import sys
import time

import numpy as np

from ..bench import Case, Result, register

TARGETS = (1, 10, 50, 200)
TARGET_CLUTTER = 20
CLUTTER = (0, 100, 1000, 10000)
STONESOUP = {'t1', 't10', 't50', 't200', 'c0', 'c100', 'c1000'}
LIMITS = {'t1': 0.35e-3, 't200': 3e-3, 'c10000': 0.1}
GATE_M = 40.0
P_D = 0.9
HALF = 500.0
R0 = np.diag([25.0, 25.0])
Q = 0.01                       # acceleration PSD: our default noise_cv
SPEED_MAX = 15.0
STONESOUP_VERSION = '1.9.1'
MISSING = f'SKIPPED: stonesoup not installed (pip install -r requirements-bench.txt for stonesoup=={STONESOUP_VERSION})'


def scans(n_clutter: int, n_scans: int, seed: int = 7, n_targets: int = 1
          ) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
    """``(t, z, R, rho)`` per scan: the targets (each with probability P_D) and Poisson clutter.

    The first target starts at (-400, -200) m with velocity (4, 2) m/s; further ones start
    uniformly in the area with 2-5 m/s in a uniform direction (drawn from ``seed + 1``).
    """
    rng = np.random.default_rng(seed)
    rho = max(n_clutter, 1) / (2 * HALF) ** 2
    start, vel = np.array([[-400.0, -200.0]]), np.array([[4.0, 2.0]])
    if n_targets > 1:
        trng = np.random.default_rng(seed + 1)
        heading = trng.uniform(0, 2 * np.pi, n_targets - 1)
        speed = trng.uniform(2.0, 5.0, n_targets - 1)
        start = np.concatenate((start, trng.uniform(-0.9 * HALF, 0.9 * HALF, (n_targets - 1, 2))))
        vel = np.concatenate((vel, speed[:, None] * np.stack((np.cos(heading), np.sin(heading)), axis=1)))
    out = []
    for k in range(n_scans):
        clutter = rng.uniform(-HALF, HALF, (rng.poisson(n_clutter), 2))
        if n_targets == 1:
            seen = np.array([rng.random() < P_D])
            noise = rng.multivariate_normal([0.0, 0.0], R0, 1) if seen[0] else np.zeros((0, 2))
        else:
            seen = rng.random(n_targets) < P_D
            noise = rng.multivariate_normal([0.0, 0.0], R0, int(seen.sum()))
        z = np.concatenate(((start + vel * (k % 200))[seen] + noise, clutter))
        out.append((float(k), z, np.broadcast_to(R0, (len(z), 2, 2)).copy(), np.full(len(z), rho)))
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
_MEDIANS: dict[str, float] = {}


def _rows() -> dict[str, tuple[int, int]]:
    """Row key -> (targets, clutter per scan)."""
    rows = {f't{n}': (n, TARGET_CLUTTER) for n in TARGETS}
    rows.update({f'c{n}': (1, n) for n in CLUTTER})
    return rows


def _ours(n_clutter: int, name: str, n_targets: int = 1, n_scans: int = 400, warmup: int = 40):
    def make():
        from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig
        cfg = TrackerConfig.from_flat({'detection.probability': P_D, 'clutter.source': 'detection',
                                       'imm.noise_cv': Q, 'init.speed_max': SPEED_MAX})

        def step(tracker, scan):
            tracker.step(*scan)
            return tracker.n_tracks
        stepper = _Stepper(lambda: ImmIpdaTracker(cfg), step, scans(n_clutter, n_scans, n_targets=n_targets),
                           warmup=warmup)
        _STEPPERS[name] = stepper
        return stepper
    return make


def _stonesoup(n_clutter: int, name: str, warmup: int, n_targets: int = 1, n_scans: int = 60):
    def make():
        try:
            import stonesoup
        except ImportError:
            print(f'  {name}: {MISSING}', file=sys.stderr)
            return lambda: math.nan
        if stonesoup.__version__ != STONESOUP_VERSION:
            print(f'  {name}: stonesoup {stonesoup.__version__} installed, the comparison was set up for '
                  f'{STONESOUP_VERSION}', file=sys.stderr)
        data = _stonesoup_scans(n_clutter, warmup + n_scans, n_targets)
        rho = max(n_clutter, 1) / (2 * HALF) ** 2

        def step(tracker, scan):
            return len(next(tracker)[1])
        stepper = _Stepper(lambda: _stonesoup_tracker(data, rho), step, data, warmup=warmup)
        _STEPPERS[name] = stepper
        return stepper
    return make


def _stonesoup_scans(n_clutter: int, n_scans: int, n_targets: int = 1):
    from datetime import datetime, timedelta

    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import Detection
    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R0)
    t0 = datetime(2025, 1, 1)
    out = []
    for t, z, _, _ in scans(n_clutter, n_scans, n_targets=n_targets):
        ts = t0 + timedelta(seconds=t)
        out.append((ts, {Detection(np.array([[a], [b]]), timestamp=ts, measurement_model=model) for a, b in z}))
    return out


def _stonesoup_tracker(data, rho):
    from stonesoup.dataassociator.tree import DetectionKDTreeGNN2D, KDTreePDA
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
        data_associator=DetectionKDTreeGNN2D(
            DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3), predictor, updater,
            max_distance=GATE_M))
    tracker = MultiTargetMixtureTracker(
        initiator=initiator, deleter=deleter(), detector=iter(data), updater=updater,
        data_associator=KDTreePDA(PDAHypothesiser(predictor, updater, clutter_spatial_density=rho, prob_detect=P_D,
                                                  prob_gate=0.99), predictor, updater, max_distance=GATE_M))
    return iter(tracker)


def _derived(name: str, n_detections: float, previous: tuple[str, float, float] | None = None):
    """Figures beside a row; ``previous = (case name, its x, this row's x)`` gives the growth exponent."""
    def derived(r: Result) -> dict:
        stepper = _STEPPERS.get(name)
        if stepper is None or math.isnan(r.median_s):
            return {'note': MISSING}
        _MEDIANS[name] = r.median_s
        out = {'us_per_detection': r.median_s * 1e6 / max(n_detections, 1.0),
               'tracks': float(np.mean(stepper.tracks)) if stepper.tracks else math.nan}
        if previous is not None and previous[0] in _MEDIANS:
            out['growth'] = math.log(r.median_s / _MEDIANS[previous[0]]) / math.log(previous[2] / previous[1])
        return out
    return derived


def _series_previous(key: str) -> tuple[str, float, float] | None:
    """The row before ``key`` in its series (targets, or clutter > 0), as ``_derived`` takes it."""
    series = [f't{n}' for n in TARGETS] if key.startswith('t') else [f'c{n}' for n in CLUTTER if n > 0]
    if key not in series or series.index(key) == 0:
        return None
    prev = series[series.index(key) - 1]
    return f'tracking.imm_ipda.{prev}', float(prev[1:]), float(key[1:])


_REPEATS = {'t1': 150, 't10': 150, 't50': 100, 't200': 60, 'c0': 150, 'c100': 150, 'c1000': 60, 'c10000': 15}
_SS = {'t1': (30, 30), 't10': (10, 20), 't50': (6, 8), 't200': (4, 4), 'c0': (30, 30), 'c100': (10, 20),
       'c1000': (4, 4)}

for _key, (_t, _c) in _rows().items():
    _name = f'tracking.imm_ipda.{_key}'
    register(Case(
        name=_name, group='tracking', self_timed=True, repeats=_REPEATS[_key],
        make=_ours(_c, _name, _t, n_scans=400 if _c < 10000 else 60, warmup=40 if _c < 10000 else 10),
        compare_to=f'tracking.stonesoup.{_key}' if _key in STONESOUP else None,
        limit_s=LIMITS.get(_key), derived=_derived(_name, _c + P_D * _t, _series_previous(_key)),
        description=f'IMM-IPDA, 3 modes: one scan, {_t} CV target(s) (P_D 0.9) + {_c} clutter/scan over 1 km^2'))
    if _key in STONESOUP:
        _sname, (_warm, _reps) = f'tracking.stonesoup.{_key}', _SS[_key]
        register(Case(
            name=_sname, group='tracking', make=_stonesoup(_c, _sname, _warm, _t, _reps + 2), self_timed=True,
            repeats=_reps, derived=_derived(_sname, _c + P_D * _t),
            description=f'Stone Soup {STONESOUP_VERSION} MultiTargetMixtureTracker + KDTreePDA + '
                        f'MultiMeasurementInitiator, same detections ({_t} target(s), {_c} clutter/scan)'))


# ---------------------------------------------------------------- 20,000 detections per scan
HEAVY_DETECTIONS, HEAVY_SCANS, HEAVY_HALF = 20000, 100, 2000.0
_HEAVY_CHILD = """
import json, resource, sys, time
import numpy as np
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig
n, scans, half = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
rng = np.random.default_rng(11)
trk = ImmIpdaTracker(TrackerConfig.from_flat({'clutter.source': 'detection'}))
rho = np.full(n, n / (2 * half) ** 2)
seconds, tracks, pairs = [], [], []
for k in range(scans):
    z = rng.uniform(-half, half, (n, 2))
    t0 = time.perf_counter()
    trk.step(float(k), z, None, rho)
    seconds.append(time.perf_counter() - t0)
    tracks.append(trk.report.n_tracks)
    pairs.append(trk.report.n_pairs)
print(json.dumps({'seconds': seconds, 'tracks': max(tracks), 'pairs': max(pairs),
                  'peak_rss_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""
_HEAVY: dict = {}


def _heavy():
    def run():
        from sonar_tracking.core.allocator import allocator_env
        done = subprocess.run([sys.executable, '-c', _HEAVY_CHILD, str(HEAVY_DETECTIONS), str(HEAVY_SCANS),
                               str(HEAVY_HALF)], capture_output=True, text=True, env=allocator_env(), check=False)
        if done.returncode != 0:
            raise RuntimeError(f'the 20,000-detection run failed: {done.stderr[-2000:]}')
        _HEAVY.update(json.loads(done.stdout.strip().splitlines()[-1]))
        return _HEAVY['seconds']
    return lambda: run


def _heavy_derived(r: Result) -> dict:
    return {'peak_rss_mb': _HEAVY.get('peak_rss_mb', math.nan), 'max_tracks': _HEAVY.get('tracks', 0),
            'max_pairs': _HEAVY.get('pairs', 0), 'max_ms': r.max_s * 1e3}


register(Case(
    name='tracking.imm_ipda.d20000', group='tracking', make=_heavy(), self_timed=True, repeats=1,
    derived=_heavy_derived,
    description=f'IMM-IPDA: {HEAVY_DETECTIONS} uniform detections/scan over 4 km x 4 km, {HEAVY_SCANS} scans, '
                f'child process with the allocator settings (time per scan, peak RSS)'))

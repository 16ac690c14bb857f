"""IMM-IPDA tracker speed (issue 5), against Stone Soup 1.9.1 on identical detections.

Scenario: one constant-velocity target seen with P_D 0.9 and Poisson clutter uniform over
1000 m x 1000 m, N clutter detections per scan on average, one scan per second, measurement
covariance diag(25, 25) m^2; the same seeded detections for every tracker. Each repeat times one
scan (``tracker.step``, including gating, update, initiation and track management) after a
warm-up that lets the track population settle; the table gives the median over scans.

* ``tracking.imm_ipda.cN``: ours, 3 modes (CV, CTR left and right), default settings with the true
  clutter density.
* ``tracking.stonesoup.cN``: Stone Soup 1.9.1 ``MultiTargetMixtureTracker`` with ``PDA``
  (``PDAHypothesiser``: same P_D, P_G 0.99, clutter density), one CV model with the same process
  noise, ``MultiMeasurementInitiator`` (2 points, GNN with a 3-sigma Mahalanobis gate, prior
  velocity variance as ours), tracks deleted after 3 scans without an update or when their
  position variance exceeds ours (30 m std per axis). Stone Soup is a bench extra
  (``pip install -r requirements-bench.txt``); without it these cases say so in the table and
  report no time.
"""
from __future__ import annotations

import gc
import math
import sys
import time

import numpy as np

from ..bench import Case, Result, register

CLUTTER = (20, 50, 100, 200, 400)
STONESOUP = (20, 400)
P_D = 0.9
HALF = 500.0
R0 = np.diag([25.0, 25.0])
Q = 0.01                       # acceleration PSD: our default noise_cv
SPEED_MAX = 15.0
STONESOUP_VERSION = '1.9.1'
MISSING = f'SKIPPED: stonesoup not installed (pip install -r requirements-bench.txt for stonesoup=={STONESOUP_VERSION})'


def scans(n_clutter: int, n_scans: int, seed: int = 7) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
    """``(t, z, R, rho)`` per scan: the target (with probability P_D) and Poisson clutter."""
    rng = np.random.default_rng(seed)
    rho = n_clutter / (2 * HALF) ** 2
    start, vel = np.array([-400.0, -200.0]), np.array([4.0, 2.0])
    out = []
    for k in range(n_scans):
        clutter = rng.uniform(-HALF, HALF, (rng.poisson(n_clutter), 2))
        parts = [clutter]
        if rng.random() < P_D:
            parts.insert(0, (start + vel * (k % 200))[None] + rng.multivariate_normal([0.0, 0.0], R0, 1))
        z = np.concatenate(parts)
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


def _ours(n_clutter: int, name: str):
    def make():
        from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig
        cfg = TrackerConfig.from_flat({'detection.probability': P_D, 'clutter.source': 'detection',
                                       'imm.noise_cv': Q, 'init.speed_max': SPEED_MAX})

        def step(tracker, scan):
            tracker.step(*scan)
            return tracker.n_tracks
        stepper = _Stepper(lambda: ImmIpdaTracker(cfg), step, scans(n_clutter, 400), warmup=40)
        _STEPPERS[name] = stepper
        return stepper
    return make


def _stonesoup(n_clutter: int, name: str, warmup: int):
    def make():
        try:
            import stonesoup
        except ImportError:
            print(f'  {name}: {MISSING}', file=sys.stderr)
            return lambda: math.nan
        if stonesoup.__version__ != STONESOUP_VERSION:
            print(f'  {name}: stonesoup {stonesoup.__version__} installed, the comparison was set up for '
                  f'{STONESOUP_VERSION}', file=sys.stderr)
        data = _stonesoup_scans(n_clutter, warmup + 60)
        rho = n_clutter / (2 * HALF) ** 2

        def step(tracker, scan):
            return len(next(tracker)[1])
        stepper = _Stepper(lambda: _stonesoup_tracker(data, rho), step, data, warmup=warmup)
        _STEPPERS[name] = stepper
        return stepper
    return make


def _stonesoup_scans(n_clutter: int, n_scans: int):
    from datetime import datetime, timedelta

    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import Detection
    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R0)
    t0 = datetime(2025, 1, 1)
    out = []
    for t, z, _, _ in scans(n_clutter, n_scans):
        ts = t0 + timedelta(seconds=t)
        out.append((ts, {Detection(np.array([[a], [b]]), timestamp=ts, measurement_model=model) for a, b in z}))
    return out


def _stonesoup_tracker(data, rho):
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import PDA
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
    tracker = MultiTargetMixtureTracker(
        initiator=initiator, deleter=deleter(), detector=iter(data), updater=updater,
        data_associator=PDA(PDAHypothesiser(predictor, updater, clutter_spatial_density=rho, prob_detect=P_D,
                                            prob_gate=0.99)))
    return iter(tracker)


def _derived(name: str, n_clutter: int):
    def derived(r: Result) -> dict:
        stepper = _STEPPERS.get(name)
        if stepper is None or math.isnan(r.median_s):
            return {'note': MISSING}
        return {'us_per_detection': r.median_s * 1e6 / (n_clutter + P_D),
                'tracks': float(np.mean(stepper.tracks)) if stepper.tracks else math.nan}
    return derived


for _n in CLUTTER:
    _name = f'tracking.imm_ipda.c{_n}'
    register(Case(
        name=_name, group='tracking', make=_ours(_n, _name), self_timed=True, repeats=150,
        compare_to=f'tracking.stonesoup.c{_n}' if _n in STONESOUP else None,
        limit_s={20: 0.5e-3, 400: 5e-3}.get(_n), derived=_derived(_name, _n),
        description=f'IMM-IPDA, 3 modes: one scan, 1 CV target (P_D 0.9) + {_n} clutter/scan over 1 km^2 (core)'))

for _n, _warm, _reps in ((20, 30, 30), (400, 6, 5)):
    _name = f'tracking.stonesoup.c{_n}'
    register(Case(
        name=_name, group='tracking', make=_stonesoup(_n, _name, _warm), self_timed=True, repeats=_reps,
        derived=_derived(_name, _n),
        description=f'Stone Soup {STONESOUP_VERSION} MultiTargetMixtureTracker + PDA + MultiMeasurementInitiator, '
                    f'same detections ({_n} clutter/scan)'))

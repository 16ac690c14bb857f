"""Amplitude statistics (ESC eqs. 13-16, Algorithm 1 line 3) measured on simulated harbour scans."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.sim import (
    AmplitudeConfig,
    AmplitudeModel,
    HarbourConfig,
    HarbourSonar,
    Scene,
    Target,
    exponential_pd,
    exponential_pfa,
)
from sonar_tracking.sim.motion import StaticTrajectory
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY


def binomial_ok(k: int, n: int, p: float, sigmas: float = 5.0) -> bool:
    return abs(k / n - p) <= sigmas * math.sqrt(p * (1 - p) / n)


@pytest.mark.parametrize('lam', [0.8, 1.2, 1.6])
def test_false_alarm_rate_matches_eq16(lam):
    sonar = HarbourSonar(HarbourConfig())
    scene = Scene([], StaticTrajectory(*HARBOUR_SONAR_XY), lam=lam)
    rng = np.random.default_rng(int(lam * 10))
    amps = np.stack([sonar.next_sector(scene, rng).amplitudes for _ in range(150)])
    n = amps.size
    for tau in (1.0, 2.0, 3.0, 4.0, 6.0):
        p = float(exponential_pfa(lam, tau))
        k = int((amps > tau).sum())
        assert binomial_ok(k, n, p), (lam, tau, k / n, p)


@pytest.mark.parametrize('lam', [0.8, 1.6])
def test_detection_probability_matches_algorithm1_at_8db(lam):
    # 60 static targets in distinct cells; each scan gives one target-cell sample per target.
    cfg = HarbourConfig()
    sonar = HarbourSonar(cfg)
    g = sonar.geometry
    rng = np.random.default_rng(7)
    ii, jj = rng.choice(g.n_bins, 60, replace=False), rng.choice(g.n_beams, 60, replace=False)
    x0, y0 = HARBOUR_SONAR_XY
    targets = [Target(k, StaticTrajectory(x0 + g.ranges()[i] * math.cos(g.bearings()[j]),
                                          y0 + g.ranges()[i] * math.sin(g.bearings()[j])), snr_db=8.0)
               for k, (i, j) in enumerate(zip(ii, jj))]
    scene = Scene(targets, StaticTrajectory(x0, y0), lam=lam)
    samples = np.concatenate([sonar.next_sector(scene, rng).amplitudes[ii, jj] for _ in range(300)])
    for tau in (2.0, 4.0, 6.0):
        p = float(exponential_pd(lam, tau, 8.0))
        assert binomial_ok(int((samples > tau).sum()), samples.size, p), (lam, tau)
        # Algorithm 1, line 3: P_fa = P_D ** (1 + SNR).
        assert exponential_pfa(lam, tau) == pytest.approx(p ** (1 + 10 ** 0.8))


@pytest.mark.parametrize('law', ['exponential', 'rayleigh', 'weibull'])
def test_every_clutter_law_has_mean_one_over_lambda(law):
    model = AmplitudeModel(AmplitudeConfig(distribution=law, weibull_shape=2.5))
    s = model.clutter(np.full(400_000, 1.25), np.random.default_rng(3))
    assert s.mean() == pytest.approx(0.8, rel=0.01)


def test_rayleigh_law_has_the_shape_of_eq13():
    s = AmplitudeModel(AmplitudeConfig(distribution='rayleigh')).unit(np.random.default_rng(4), 400_000)
    # Scaled so the mean is 1: s * sqrt(pi/2) follows p(x) = x exp(-x^2 / 2), whose P(x > a) = exp(-a^2 / 2).
    x = s * math.sqrt(math.pi / 2)
    for a in (0.5, 1.0, 2.0, 3.0):
        assert (x > a).mean() == pytest.approx(math.exp(-a * a / 2), abs=4e-3)

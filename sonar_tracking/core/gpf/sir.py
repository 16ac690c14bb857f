"""The SIR particle filter baseline (FLS paper Figure 13, "PF"): particles that live between frames.

Unlike the GPF, each track keeps its K weighted particles. Per frame they are moved by sampling
the same motion model as the GPF's prediction (:func:`.gaussian.propagate`), weighted by the same
fused cue likelihood, and resampled (systematic resampling, every frame: sampling importance
resampling). The estimate is the weighted mean before resampling. A frame that does not see the
target leaves the particles unweighted and spreads them about their mean as the GPF widens its
covariance (step 3).

After resampling, the particles are *roughened* (Gordon, Salmond and Smith's bootstrap filter):
jittered so that their position spread is at least the GPF's posterior floor ``min_std``. The
cue likelihood puts most weight on a few particles, resampling copies those, and the motion model
alone spreads them by about 0.2 m in a 5 s frame, less than a towed target wanders; without the
jitter the SIR's cloud misses the target, as a GPF posterior floored at 0.25 m does (numbers in
``docs/experiments/2026-11-21-fls-gpf-study.md``). One floor for both particle methods keeps the
comparison about how they use a frame.
"""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.gpf.gaussian import floor_position, motion_matrices, sample_gaussian, weighted_moments
from sonar_tracking.core.gpf.gaussian import propagate as _propagate

__all__ = ['propagate', 'resample', 'spread', 'roughen']


def propagate(particles: np.ndarray, dt: float, q: float, rng: np.random.Generator) -> np.ndarray:
    """Particles moved over ``dt`` by sampling the constant-velocity model."""
    F, Q = motion_matrices(dt, q)
    return _propagate(particles, F, Q, rng)


def resample(particles: np.ndarray, weights: np.ndarray, rng: np.random.Generator
             ) -> tuple[np.ndarray, np.ndarray]:
    """Systematic resampling: K particles drawn with probabilities ``weights``, then equal weights."""
    k = len(weights)
    positions = (rng.random() + np.arange(k)) / k
    cum = np.cumsum(weights)
    cum[-1] = 1.0
    idx = np.searchsorted(cum, positions, side='right')
    return particles[np.minimum(idx, k - 1)].copy(), np.full(k, 1.0 / k)


def spread(particles: np.ndarray, weights: np.ndarray, inflation: float, cov: np.ndarray) -> np.ndarray:
    """Particles moved away from their weighted mean by ``sqrt(inflation)`` (their covariance times
    ``inflation``); ``cov`` is the widened covariance the GPF would have, which caps the spread."""
    mean, current = weighted_moments(particles, weights)
    dev = particles - mean
    factor = np.sqrt(max(1.0, min(inflation, float(np.trace(cov[:2, :2])) / max(float(np.trace(current[:2, :2])),
                                                                                  1e-300))))
    return mean + dev * factor


def roughen(particles: np.ndarray, variance: float, rng: np.random.Generator) -> np.ndarray:
    """Equal-weight particles (after :func:`resample`) roughened: Gaussian jitter added to their
    positions so that their position covariance has eigenvalues of at least ``variance`` (the
    jitter's covariance is the floored covariance minus the particles' own)."""
    _, cov = weighted_moments(particles)
    extra = floor_position(cov, variance)[:2, :2] - cov[:2, :2]
    if np.trace(extra) <= 1e-15:
        return particles
    out = particles.copy()
    out[:, :2] += sample_gaussian(np.zeros(2), extra, len(particles), rng)
    return out

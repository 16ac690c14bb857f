"""existence.confirm_distance: a track is confirmed only once it has moved from where it started, so
a static echo (frozen speckle, a rock) stays tentative however often it is detected."""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig

R = np.diag([0.01, 0.01])


def _run(confirm_distance: float, velocity: tuple[float, float], scans: int = 80, seed: int = 3):
    """One target at 20 Hz, detected every scan with 0.1 m noise; returns the confirmed flags per scan
    and the scan at which the target had moved confirm_distance."""
    rng = np.random.default_rng(seed)
    trk = ImmIpdaTracker(TrackerConfig.from_flat({
        'clutter.source': 'constant', 'clutter.density': 1e-3, 'detection.probability': 0.9,
        'existence.confirm': 0.99, 'existence.survival': 0.995, 'init.speed_max': 3.0,
        'existence.confirm_distance': confirm_distance}))
    confirmed = []
    for k in range(scans):
        t = 0.05 * k
        z = np.array([[10.0 + velocity[0] * t, 2.0 + velocity[1] * t]]) + rng.normal(0.0, 0.1, (1, 2))
        out = trk.step(t, z, R[None])
        confirmed.append(bool(np.any(out['confirmed'])))
    return np.array(confirmed)


def test_a_static_echo_is_confirmed_without_the_rule_and_never_with_it():
    assert _run(0.0, (0.0, 0.0)).any()
    assert not _run(0.5, (0.0, 0.0)).any()


def test_a_moving_target_is_confirmed_once_it_has_moved_the_distance():
    without = _run(0.0, (1.0, 0.0))
    with_rule = _run(0.5, (1.0, 0.0))
    first, first_rule = int(np.argmax(without)), int(np.argmax(with_rule))
    assert without.any() and with_rule.any()
    # 0.5 m at 1 m/s is 10 scans of 0.05 s; the estimate lags the truth by a little.
    assert first_rule >= first and first_rule >= 8
    assert with_rule[first_rule:].all(), 'once confirmed, the track stays confirmed'

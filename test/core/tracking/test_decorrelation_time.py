"""existence.decorrelation_time: frames closer together than tau weigh as one scan in the existence
update, so a fade of a fraction of a second does not end a track at frame rate, confirmation takes
about the same time in seconds at any frame rate, and scans tau or more apart are updated as in the
paper."""
from __future__ import annotations

import numpy as np
import pytest

import sonar_tracking.core.tracking.tracker as tracker_module
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig

R = np.diag([0.01, 0.01])
BASE = {'clutter.source': 'constant', 'clutter.density': 1e-3, 'detection.probability': 0.8,
        'existence.confirm': 0.99, 'existence.survival': 0.995, 'init.speed_max': 3.0,
        'imm.turn_rate_ccw_deg': 20.0, 'imm.turn_rate_cw_deg': 20.0, 'imm.noise_cv': 0.2, 'imm.noise_ctr': 0.2}


def _tracker(tau: float, **extra) -> ImmIpdaTracker:
    return ImmIpdaTracker(TrackerConfig.from_flat({**BASE, 'existence.decorrelation_time': tau, **extra}))


def _target(t: float) -> np.ndarray:
    return np.array([[10.0 + 0.8 * t, 2.0 + 0.3 * t]])


def _fade(tau: float, fade: tuple[float, float] = (3.0, 3.6), rate: float = 20.0, seconds: float = 5.0, seed: int = 3):
    """A target at 0.8 m/s seen every frame but during ``fade`` [s]: the ids of the confirmed tracks
    just before the fade and at the end, and the least existence of the first one during the fade."""
    rng = np.random.default_rng(seed)
    trk = _tracker(tau)
    before: set[int] = set()
    least = 1.0
    out = trk.step(0.0, _target(0.0), R[None])
    for k in range(1, int(seconds * rate) + 1):
        t = k / rate
        seen = not fade[0] <= t < fade[1]
        z = _target(t) + rng.normal(0.0, 0.1, (1, 2)) if seen else np.zeros((0, 2))
        out = trk.step(t, z, R[None] if seen else np.zeros((0, 2, 2)))
        if t < fade[0]:
            before = {int(i) for i in out['track_id'][out['confirmed'] != 0]}
        elif seen is False and before:
            first = out[out['track_id'] == min(before)]
            least = min(least, float(first['existence'][0]) if len(first) else 0.0)
    return before, {int(i) for i in out['track_id'][out['confirmed'] != 0]}, least


def test_default_is_off():
    assert TrackerConfig().existence.decorrelation_time == 0.0


def test_a_fade_of_twelve_frames_ends_the_track_without_the_rule_and_not_with_it():
    before, after, least = _fade(0.0)
    assert before, 'the target is confirmed before the fade'
    assert not before & after and least < 0.01, 'terminated within 0.6 s of misses, a new track after'
    before, after, least = _fade(0.4)
    assert before and before <= after, 'the same track goes on after the fade'
    assert least > 0.1


def _confirm_time(tau: float, rate: float) -> float:
    """Seconds from the first detection of a target seen every frame to its confirmation."""
    trk = _tracker(tau)
    for k in range(int(5 * rate)):
        t = k / rate
        out = trk.step(t, _target(t), R[None])
        if np.any(out['confirmed']):
            return t
    return float('inf')


def test_confirmation_takes_about_the_same_seconds_at_any_frame_rate():
    slow, fast = _confirm_time(0.0, 10.0), _confirm_time(0.0, 40.0)
    assert slow >= 3 * fast, 'counted frame by frame, four times the frames confirm four times sooner'
    times = [_confirm_time(0.4, rate) for rate in (10.0, 20.0, 40.0)]
    assert max(times) < 5 and max(times) - min(times) <= 0.15, times
    assert min(times) > 2 * fast


@pytest.mark.parametrize('method', ['ipda', 'jipda'])
def test_scans_tau_or_more_apart_are_updated_as_in_the_paper(method):
    rng = np.random.default_rng(5)
    paper, rule = _tracker(0.0, **{'association.method': method}), _tracker(1.0, **{'association.method': method})
    for k in range(12):
        z = np.concatenate([_target(float(k)), rng.uniform(-20, 40, (6, 2))])
        a = paper.step(float(k), z, np.repeat(R[None], len(z), axis=0))
        b = rule.step(float(k), z, np.repeat(R[None], len(z), axis=0))
        assert np.array_equal(a, b)


def test_the_weight_is_the_same_in_chunks(monkeypatch):
    rng = np.random.default_rng(11)
    scans = [rng.uniform(-30, 30, (60, 2)) for _ in range(8)]
    ref = _tracker(0.4)
    outs = [ref.step(0.05 * k, z, None).copy() for k, z in enumerate(scans)]
    monkeypatch.setattr(tracker_module, '_CHUNK_PAIRS', 50)
    chunked = _tracker(0.4)
    for k, z in enumerate(scans):
        out = chunked.step(0.05 * k, z, None)
        assert np.array_equal(out['track_id'], outs[k]['track_id'])
        np.testing.assert_allclose(out['existence'], outs[k]['existence'], rtol=1e-10, atol=1e-12)
    assert chunked.report.n_pairs > 50

"""existence.confirm_distance after a lapse: a tentative track whose existence fell below existence.confirm_lapse
(1/2 by default) measures its distance afresh, so a track that loses one still echo and picks up another in
its gate (two peaks of frozen speckle) is not confirmed for the jump between them, while a moving target still
is."""
from __future__ import annotations

import numpy as np

from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig

# A diver-sized spread (cells.target_size 1.8 m): the gate reaches 2 m.
R = np.diag([0.27, 0.27])
A, B = np.array([10.0, 2.0]), np.array([11.6, 2.0])


def _tracker(**settings) -> ImmIpdaTracker:
    return ImmIpdaTracker(TrackerConfig.from_flat({
        'clutter.source': 'constant', 'clutter.density': 1e-3, 'detection.probability': 0.8,
        'existence.confirm': 0.99, 'existence.survival': 0.995, 'init.speed_max': 3.0,
        'existence.confirm_distance': 1.4, **settings}))


def _hop(gap: int, seed: int = 3, **settings):
    """Echo A every frame for 2 s, nothing for ``gap`` frames, then echo B (1.6 m away) every frame for
    3 s, at 20 Hz with 5 cm jitter: whether a track was ever confirmed, the least existence of the
    track on A during the gap, and whether that track took B."""
    rng = np.random.default_rng(seed)
    trk = _tracker(**settings)
    confirmed, least, first = False, 1.0, None
    frames = [A] * 40 + [None] * gap + [B] * 60
    out = None
    for k, echo in enumerate(frames):
        z = np.zeros((0, 2)) if echo is None else echo[None] + rng.normal(0.0, 0.05, (1, 2))
        out = trk.step(k / 20, z, np.repeat(R[None], len(z), axis=0))
        confirmed |= bool(np.any(out['confirmed']))
        if k == 39:
            first = int(out['track_id'][np.argmax(out['existence'])])
        elif echo is None and first is not None:
            mine = out[out['track_id'] == first]
            least = min(least, float(mine['existence'][0]) if len(mine) else 0.0)
    mine = out[out['track_id'] == first]
    took_b = bool(len(mine)) and float(np.hypot(*(np.array([mine['x'][0], mine['y'][0]]) - B))) < 0.3
    return confirmed, least, took_b


def test_a_track_that_lapsed_and_jumped_to_another_still_echo_is_not_confirmed():
    confirmed, least, took_b = _hop(6)
    assert least < 0.5 and took_b, 'the set-up: the track on A lapses in the gap and takes B after it'
    assert not confirmed


def test_a_jump_without_a_lapse_is_still_measured_from_the_first_echo():
    # One missed frame: the track never lapses, and the 1.6 m move from A to B counts.
    confirmed, least, took_b = _hop(1)
    assert least > 0.5 and took_b and confirmed


def test_a_higher_lapse_counts_a_shorter_gap_as_lost():
    # With decorrelated evidence (the imaging presets) existence falls slowly: in 8 missed frames it
    # stays above 1/2 but falls below 0.9, so with confirm_lapse 0.9 the distance is measured from B,
    # where the track sits still.
    slow = {'existence.decorrelation_time': 0.3}
    confirmed, least, took_b = _hop(8, **slow)
    assert 0.5 < least < 0.9 and took_b and confirmed
    assert _hop(8, **slow, **{'existence.confirm_lapse': 0.9}) == (False, least, True)


def test_a_moving_target_that_fades_is_confirmed_after_it_moves_the_distance_again():
    rng = np.random.default_rng(4)
    trk = _tracker()
    first_confirmed = None
    for k in range(120):
        t = k / 20
        seen = not 30 <= k < 36            # a fade of 0.3 s early in its life
        z = np.array([[10.0 + 0.8 * t, 2.0]]) + rng.normal(0.0, 0.05, (1, 2)) if seen else np.zeros((0, 2))
        out = trk.step(t, z, np.repeat(R[None], len(z), axis=0))
        if first_confirmed is None and np.any(out['confirmed']):
            first_confirmed = t
    assert first_confirmed is not None and first_confirmed < 4.0

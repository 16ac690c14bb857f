"""Motion models (eqs. 3-4), process noise, Markov chains (eqs. 21, 24, 40)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.tracking import (
    ConstantTurn,
    ConstantVelocity,
    TrackingInputError,
    mode_transition_matrix,
    position_matrix,
    predict_existence,
    update_existence,
    white_noise_acceleration,
)
from sonar_tracking.sim.motion import ScriptedTrajectory, Segment


@pytest.mark.parametrize('ndim', [1, 2, 3])
def test_constant_velocity_is_eq3_in_any_dimension(ndim):
    F = ConstantVelocity(ndim).transition(0.7)
    eye = np.eye(ndim)
    assert np.array_equal(F, np.block([[eye, 0.7 * eye], [0 * eye, eye]]))
    # A flow: F(a) F(b) = F(a + b).
    np.testing.assert_allclose(ConstantVelocity(ndim).transition(0.3) @ ConstantVelocity(ndim).transition(0.4), F)


def test_constant_turn_is_eq4_and_turns_counter_clockwise_for_positive_rate():
    w, dt = math.radians(3.0), 1.5
    F = ConstantTurn(w).transition(dt)
    s, c = math.sin(w * dt), math.cos(w * dt)
    expected = np.array([[1, 0, s / w, -(1 - c) / w], [0, 1, (1 - c) / w, s / w], [0, 0, c, -s], [0, 0, s, c]])
    np.testing.assert_allclose(F, expected, rtol=1e-15, atol=1e-15)
    # REP-103: +Omega turns the velocity from x towards y.
    v = ConstantTurn(math.pi / 2).transition(1.0) @ np.array([0.0, 0.0, 1.0, 0.0])
    np.testing.assert_allclose(v[2:], [0.0, 1.0], atol=1e-15)
    # Flow property and the zero-rate limit.
    np.testing.assert_allclose(ConstantTurn(w).transition(0.5) @ ConstantTurn(w).transition(1.0), F, atol=1e-12)
    np.testing.assert_allclose(ConstantTurn(1e-13).transition(2.0), ConstantVelocity(2).transition(2.0), atol=1e-12)
    np.testing.assert_array_equal(ConstantTurn(0.0).transition(2.0), ConstantVelocity(2).transition(2.0))


@pytest.mark.parametrize('rate_deg', [3.0, -3.0])
def test_turn_models_follow_the_simulator_truth_exactly(rate_deg):
    """Our ccw/cw modes are the same motion as the simulator's Table 2 segments (no sign slip)."""
    w = math.radians(rate_deg)
    traj = ScriptedTrajectory(50.0, 200.0, 12.0, 0.0, (Segment(30.0, w),))
    F = ConstantTurn(w).transition(1.0)
    s = traj.state(0.0)
    for k in range(1, 31):
        s = F @ s
        np.testing.assert_allclose(s, traj.state(float(k)), rtol=0, atol=1e-9)


def test_bad_model_arguments_raise():
    with pytest.raises(TrackingInputError, match='ndim'):
        ConstantVelocity(0)
    with pytest.raises(TrackingInputError, match='turn_rate'):
        ConstantTurn(math.nan)


def test_position_matrix_is_eq27():
    assert np.array_equal(position_matrix(2), np.array([[1, 0, 0, 0], [0, 1, 0, 0]]))


def test_white_noise_acceleration_is_consistent_over_split_intervals():
    """Continuous model: Q(a + b) = F(b) Q(a) F(b)^T + Q(b), so irregular scans stay consistent."""
    q, a, b = 0.3, 0.4, 1.1
    F = ConstantVelocity(2).transition(b)
    lhs = white_noise_acceleration(a + b, q)
    rhs = F @ white_noise_acceleration(a, q) @ F.T + white_noise_acceleration(b, q)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-12)
    Q = white_noise_acceleration(1.0, 2.0)
    assert Q[0, 0] == pytest.approx(2.0 / 3) and Q[0, 2] == pytest.approx(1.0) and Q[2, 2] == pytest.approx(2.0)
    assert np.all(np.linalg.eigvalsh(Q) > 0)
    with pytest.raises(TrackingInputError):
        white_noise_acceleration(-1.0, 1.0)


def test_mode_transition_matrix_is_eq21():
    np.testing.assert_allclose(mode_transition_matrix(3, 0.98),
                               [[0.98, 0.01, 0.01], [0.01, 0.98, 0.01], [0.01, 0.01, 0.98]])
    assert np.array_equal(mode_transition_matrix(1, 0.5), [[1.0]])
    for n in (2, 4, 5):
        np.testing.assert_allclose(mode_transition_matrix(n, 0.9).sum(axis=1), 1.0)
    with pytest.raises(TrackingInputError):
        mode_transition_matrix(3, 0.0)


def test_existence_chain_eq24_and_posterior_eq40():
    p = np.array([0.0, 0.3, 1.0])
    np.testing.assert_allclose(predict_existence(p, 0.98, 0.01), 0.98 * p + 0.01 * (1 - p))
    pp = np.array([0.2, 0.2, 0.2, 0.2])
    lam = np.array([0.0, 1.0, 4.0, 1e300])
    np.testing.assert_allclose(update_existence(pp, lam), [0.0, 0.2, 0.8 / (1 - (1 - 4) * 0.2), 1.0])
    # Bayes with a likelihood ratio: posterior odds = prior odds * Lambda.
    post = update_existence(np.array([0.3]), np.array([2.5]))[0]
    assert post / (1 - post) == pytest.approx(0.3 / 0.7 * 2.5)
    # The 0/0 case is 0, never NaN.
    assert update_existence(np.array([1.0]), np.array([0.0]))[0] == 0.0


def test_duplicate_check_of_coincident_confirmed_tracks_stays_within_its_pair_budget():
    """3,000 confirmed tracks on one spot: 9 M near pairs; the budget bounds memory, the oldest id stays."""
    import tracemalloc

    from sonar_tracking.core.tracking.management import duplicate_tracks
    n = 3000
    x = np.zeros((4, n))
    P = np.broadcast_to(np.eye(4)[:, :, None], (4, 4, n)).copy()
    ids = np.random.default_rng(33).permutation(n) + 1
    alive = np.ones(n, dtype=bool)
    tracemalloc.start()
    try:
        for _ in range(200):
            idx = np.flatnonzero(alive)
            if len(idx) == 1:
                break
            drop = duplicate_tracks(x[:, idx], P[..., idx], np.ones(len(idx)), np.ones(len(idx), dtype=bool),
                                    ids[idx], 9.49, max_pairs=100_000)
            assert drop.any()
            alive[idx[drop]] = False
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert np.flatnonzero(alive).tolist() == [int(np.argmin(ids))]
    assert peak < 100e6

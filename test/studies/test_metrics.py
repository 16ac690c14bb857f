"""Performance measures: FTD (eqs. 47-48), CTTR, RMSE (eq. 49), OSPA and GOSPA against brute force."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sonar_tracking.core.records import TRACK_DTYPE
from sonar_tracking.studies import (
    TAU_FALSE,
    TAU_TRUE,
    MetricError,
    classify_tracks,
    confirmed_false_track_rate,
    confirmed_true_track_rate,
    evaluate_scan,
    ftd_distances,
    gospa,
    ospa,
    position_rmse,
)

P0 = np.diag([25.0, 25.0, 75.0, 75.0])


def test_paper_thresholds():
    assert (TAU_TRUE, TAU_FALSE) == (20.0, 40.0)


def test_ftd_distance_is_the_quadratic_form_of_eqs_47_48():
    truth = np.array([[0.0, 0.0, 10.0, 0.0], [500.0, 0.0, 0.0, 5.0]])
    est = np.array([[10.0, 0.0, 10.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    d = ftd_distances(truth, est, P0)
    assert d.shape == (2, 2)
    assert d[0, 0] == pytest.approx(100 / 25)
    assert d[1, 0] == pytest.approx(100 / 75)
    assert d[0, 1] == pytest.approx(490 ** 2 / 25 + (100 + 25) / 75)
    per_track = np.stack([P0, 2 * P0])
    np.testing.assert_allclose(ftd_distances(truth, est, per_track)[1], d[1] / 2)
    with pytest.raises(MetricError, match='P0'):
        ftd_distances(truth, est, np.eye(3))


def test_classification_true_false_and_in_between():
    truth = np.array([[0.0, 0.0, 0.0, 0.0]])
    # squared distances 4, 19.96, 30, 40.04 (position errors only, P0 25 m^2)
    est = np.array([[10.0, 0, 0, 0], [math.sqrt(19.96 * 25), 0, 0, 0], [math.sqrt(30 * 25), 0, 0, 0],
                    [math.sqrt(40.04 * 25), 0, 0, 0]])
    c = classify_tracks(truth, est, P0)
    assert c.label.tolist() == [1, 1, 0, -1] and c.target.tolist() == [0, 0, -1, -1]
    assert (c.n_true, c.n_false) == (2, 1)
    none = classify_tracks(np.zeros((0, 4)), est, P0)
    assert none.label.tolist() == [-1] * 4
    with pytest.raises(MetricError):
        classify_tracks(truth, est, P0, tau_true=50, tau_false=40)


def records(rows):
    out = np.zeros(len(rows), TRACK_DTYPE)
    for i, (x, y, vx, vy, conf) in enumerate(rows):
        out[i]['track_id'], out[i]['x'], out[i]['y'], out[i]['vx'], out[i]['vy'] = i + 1, x, y, vx, vy
        out[i]['confirmed'] = conf
    return out


def test_evaluate_scan_counts_one_ctt_per_target_and_its_nearest_error():
    truth = np.array([[0.0, 0.0, 10.0, 0.0], [1000.0, 0.0, 0.0, 0.0]])
    tracks = records([(3.0, 4.0, 10.0, 0.0, 1),      # CTT of target 0, error 5
                      (1.0, 0.0, 10.0, 0.0, 1),      # duplicate CTT of target 0, error 1
                      (500.0, 0.0, 0.0, 0.0, 1),     # false
                      (1000.0, 0.0, 0.0, 0.0, 0)])   # tentative: ignored
    ev = evaluate_scan(truth, tracks, P0)
    assert ev.has_ctt.tolist() == [True, False]
    assert ev.error[0] == pytest.approx(1.0) and math.isnan(ev.error[1])
    assert (ev.n_confirmed, ev.n_true, ev.n_false) == (3, 2, 1)
    with pytest.raises(MetricError, match='lack'):
        evaluate_scan(truth, np.zeros(2, [('x', 'f8')]), P0)


def test_cttr_rmse_and_cft_rate():
    has = np.array([[True, False, True], [True, True, False]])
    np.testing.assert_allclose(confirmed_true_track_rate(has), [1.0, 0.5, 0.5])
    np.testing.assert_allclose(confirmed_true_track_rate(has[:, :, None].repeat(2, axis=2)), [1.0, 0.5, 0.5])
    err = np.array([[3.0, np.nan, np.nan], [4.0, 2.0, np.nan]])
    rmse = position_rmse(err)                          # eq. (49) over the runs with a CTT
    assert rmse[0] == pytest.approx(math.sqrt((9 + 16) / 2)) and rmse[1] == pytest.approx(2.0)
    assert math.isnan(rmse[2])
    assert confirmed_false_track_rate(np.array([[0, 1, 0], [0, 0, 1]])) == pytest.approx(2 / 6)
    with pytest.raises(MetricError):
        confirmed_true_track_rate(np.ones(3, bool))


def brute_ospa(X, Y, c, p):
    m, n = len(X), len(Y)
    if m > n:
        X, Y, m, n = Y, X, n, m
    if n == 0:
        return 0.0
    best = min(sum(min(np.linalg.norm(X[i] - Y[j]), c) ** p for i, j in zip(range(m), perm))
               for perm in itertools.permutations(range(n), m))
    return ((best + c ** p * (n - m)) / n) ** (1 / p)


def brute_gospa(X, Y, c, p):
    """alpha = 2 by its definition: min over partial assignments gamma."""
    m, n = len(X), len(Y)
    best = math.inf
    for k in range(min(m, n) + 1):
        for rows in itertools.combinations(range(m), k):
            for cols in itertools.permutations(range(n), k):
                cost = sum(np.linalg.norm(X[i] - Y[j]) ** p for i, j in zip(rows, cols))
                best = min(best, cost + c ** p / 2 * (m + n - 2 * k))
    return best ** (1 / p)


def test_ospa_and_gospa_known_values():
    assert ospa([[0.0, 0.0]], [[3.0, 4.0]], c=10).distance == pytest.approx(5.0)
    assert ospa([[0.0, 0.0]], [[3.0, 4.0]], c=2).distance == pytest.approx(2.0)
    r = ospa([[0.0]], [[0.0], [100.0]], c=10, p=1)
    assert (r.distance, r.localisation, r.cardinality) == pytest.approx((5.0, 0.0, 5.0))
    assert ospa(np.zeros((0, 2)), np.zeros((0, 2)), c=5).distance == 0.0
    assert ospa(np.zeros((0, 2)), [[1.0, 1.0]], c=5).distance == 5.0
    g = gospa([[0.0, 0.0]], np.zeros((0, 2)), c=10, p=2)
    assert g.distance == pytest.approx(10 / math.sqrt(2)) and (g.missed, g.false) == (1, 0)
    g = gospa([[0.0, 0.0], [50.0, 0.0]], [[1.0, 0.0], [70.0, 0.0], [200.0, 0.0]], c=10, p=2)
    assert (g.missed, g.false) == (1, 2)
    assert g.distance ** 2 == pytest.approx(g.localisation ** 2 + (g.missed + g.false) * 100 / 2)
    assert g.localisation == pytest.approx(1.0)
    with pytest.raises(MetricError, match='cut-off'):
        ospa([[0.0]], [[1.0]], c=0)
    with pytest.raises(MetricError, match='order'):
        gospa([[0.0]], [[1.0]], c=1, p=0.5)


@pytest.mark.parametrize('p', [1.0, 2.0])
def test_ospa_and_gospa_equal_brute_force_and_are_metrics(p):
    rng = np.random.default_rng(30)
    c = 15.0
    sets = [rng.uniform(0, 40, (rng.integers(0, 5), 2)) for _ in range(25)]
    for X, Y in zip(sets, sets[1:]):
        assert ospa(X, Y, c, p).distance == pytest.approx(brute_ospa(X, Y, c, p), abs=1e-12)
        assert gospa(X, Y, c, p).distance == pytest.approx(brute_gospa(X, Y, c, p), abs=1e-12)
        assert ospa(X, Y, c, p).distance == pytest.approx(ospa(Y, X, c, p).distance)
        assert gospa(X, Y, c, p).distance == pytest.approx(gospa(Y, X, c, p).distance)
        assert ospa(X, X, c, p).distance == pytest.approx(0.0, abs=1e-12)
    for X, Y, Z in zip(sets, sets[1:], sets[2:]):
        for f in (ospa, gospa):
            assert f(X, Z, c, p).distance <= f(X, Y, c, p).distance + f(Y, Z, c, p).distance + 1e-9

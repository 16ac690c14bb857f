"""GRNN (eq. 4) and the SFS / SBS wrapper searches (Tables 3-4) on data with a known answer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.fls.grnn import GRNN, RankScaler, balanced_error
from sonar_tracking.core.fls.selection import GrnnWrapper, sbs, sfs


def test_rank_scaler_is_mid_rank_over_n():
    s = RankScaler().fit(np.array([[1.0], [2.0], [2.0], [10.0]]))
    assert s.transform(np.array([[0.0], [1.0], [2.0], [5.0], [100.0]])).ravel().tolist() == [0.0, 0.125, 0.5, 0.75,
                                                                                             1.0]


def test_prediction_is_equation_4_with_one_hot_targets():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(40, 3))
    y = np.where(x[:, 0] > 0, 'a', 'b')
    q = rng.normal(size=(7, 3))
    g = GRNN(sigma=0.3).fit(x, y)
    # Direct eq. (4), sample by sample, in the scaled space.
    xs, qs = g.scaler_.transform(x), g.scaler_.transform(q)
    s = g.bandwidth(3)
    for k in range(len(q)):
        w = np.array([math.exp(-np.sum((qs[k] - xi) ** 2) / (2 * s * s)) for xi in xs])
        p_a = sum(wi for wi, yi in zip(w, y) if yi == 'a') / w.sum()
        assert g.predict_proba(q[k:k + 1])[0] == pytest.approx([p_a, 1 - p_a], rel=1e-9)


def test_far_queries_take_the_nearest_class_and_wide_kernels_the_prior():
    x = np.array([[0.0], [1.0], [2.0], [3.0]])
    y = np.array([0, 0, 0, 1])
    assert GRNN(sigma=1e-3).fit(x, y).predict(np.array([[1e6], [-1e6]])).tolist() == [1, 0]
    assert GRNN(sigma=1e3).fit(x, y).predict_proba(np.array([[3.0]]))[0] == pytest.approx([0.75, 0.25], rel=1e-3)


def test_bad_inputs_refused_with_reasons():
    with pytest.raises(ValueError, match='sigma'):
        GRNN(sigma=0.0)
    with pytest.raises(ValueError, match='non-finite values in columns \\[1\\]'):
        GRNN().fit(np.array([[1.0, np.nan]]), np.array([0]))
    with pytest.raises(ValueError, match='3 samples but'):
        GRNN().fit(np.ones((3, 2)), np.array([0, 1]))
    with pytest.raises(ValueError, match='columns'):
        GRNN().fit(np.ones((3, 2)), np.array([0, 1, 1])).predict(np.ones((1, 3)))


def informative_data(seed: int, n: int = 240):
    """Three classes told apart by features 3 and 7 together (1-based); the other 8 are noise."""
    rng = np.random.default_rng(seed)
    y = rng.integers(0, 3, n)
    x = rng.normal(size=(n, 10))
    x[:, 2] += 3.0 * (y == 1)
    x[:, 6] += 3.0 * (y == 2)
    return x, y


def test_wrapper_error_equals_a_grnn_trained_on_the_subset():
    xt, yt = informative_data(1)
    xv, yv = informative_data(2, 120)
    w = GrnnWrapper(xt, yt, xv, yv, sigma=0.2)
    for subset in [(3,), (3, 7), (1, 3, 7), (3, 7, 9, 10), (3, 7)]:
        cols = [f - 1 for f in subset]
        want = balanced_error(yv, GRNN(0.2).fit(xt[:, cols], yt).predict(xv[:, cols]))
        assert w(subset) == pytest.approx(want, abs=1e-12)
    with pytest.raises(ValueError, match='1..10'):
        w((0, 3))


@pytest.mark.parametrize('search', [sfs, sbs])
def test_searches_find_the_informative_pair(search):
    xt, yt = informative_data(3)
    xv, yv = informative_data(4, 150)
    path = search(GrnnWrapper(xt, yt, xv, yv, sigma=0.2), range(1, 11))
    assert [len(s) for s in path.subsets] == list(range(1, 11))
    assert set(path.subset_of(2)) == {3, 7}
    assert set(path.order[:2]) == {3, 7}
    assert set(path.best) >= {3, 7} and path.errors[1] < 0.15 < path.errors[0]


def test_search_mechanics_on_a_known_criterion():
    """error(S) = sum of per-feature costs plus a penalty for size: the best subset is known."""
    cost = {1: 0.5, 2: -0.3, 3: -0.2, 4: 0.1, 5: -0.25}

    def error(s):
        return 1.0 + sum(cost[f] for f in s)
    fwd, bwd = sfs(error, cost), sbs(error, cost)
    assert fwd.order == [2, 5, 3, 4, 1] and fwd.best == (2, 3, 5)
    assert bwd.best == (2, 3, 5) and bwd.subsets[-1] == (1, 2, 3, 4, 5)
    assert fwd.errors[2] == pytest.approx(0.25)
    # Ties go to the lower feature number.
    assert sfs(lambda s: 1.0, [4, 2, 9]).order == [2, 4, 9]
    assert sfs(error, cost, max_features=2).subsets == [(2,), (2, 5)]

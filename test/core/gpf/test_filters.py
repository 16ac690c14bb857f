"""The FLS trackers' filters behind one interface (core/gpf/filters.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.gpf.filters import FILTERS, Ekf, GaussianPF, SirPF
from sonar_tracking.core.gpf.track import GpfTrack


def track(mean=(10.0, 2.0, 0.5, 0.0), var=(0.25, 0.25, 0.04, 0.04)) -> GpfTrack:
    return GpfTrack(track_id=1, mean=np.array(mean), cov=np.diag(var), template=np.zeros(0), born=0.0, stamp=0.0,
                    last_seen=0.0)


def test_methods_map_to_their_filters():
    assert {'gpf': GaussianPF, 'sir': SirPF} == FILTERS


def test_each_particle_filter_moves_weighs_and_keeps_what_it_should():
    rng = np.random.default_rng(4)
    gpf, sir = GaussianPF(), SirPF()
    a, b = track(), track()
    sir.restart(b, 400, rng)
    assert b.particles.shape == (400, 4) and np.allclose(b.weights, 1 / 400)
    gpf.predict([a], 2.0, 0.01, 400, rng)
    sir.predict([b], 2.0, 0.01, 400, rng)
    for tr in (a, b):   # 2 s at 0.5 m/s along x; position variance grown by the velocity's
        assert tr.mean[0] == pytest.approx(11.0, abs=0.1) and tr.cov[0, 0] > 0.25 + 0.04 * 4 * 0.8
    # A likelihood that wants the particles 0.4 m to the left (+y).
    for f, tr in ((gpf, a), (sir, b)):
        p = f.particles([tr], 400, rng)[0]
        w, mean, cov = f.posterior(tr, p, -0.5 * ((p[:, 1] - (tr.mean[1] + 0.4)) / 0.3) ** 2, 0.01)
        gain = tr.cov[1, 1] / (tr.cov[1, 1] + 0.3 ** 2)        # the Gaussian product's
        assert w.sum() == pytest.approx(1.0) and mean[1] == pytest.approx(tr.mean[1] + 0.4 * gain, abs=0.06)
        assert cov[1, 1] < tr.cov[1, 1]
    # The GPF's velocity is the prediction's conditional given the posterior position; the SIR's
    # is its particles' own weighted mean.
    _, mean, _ = gpf.posterior(a, gpf.particles([a], 400, rng)[0], np.zeros(400), 0.01)
    expected = a.mean[2:] + a.cov[2:, :2] @ np.linalg.solve(a.cov[:2, :2], mean[:2] - a.mean[:2])
    np.testing.assert_allclose(mean[2:], expected, atol=1e-12)
    p = sir.particles([b], 400, rng)[0]
    _, mean, _ = sir.posterior(b, p, np.zeros(400), 0.01)
    np.testing.assert_allclose(mean[2:], np.average(p[:, 2:], axis=0, weights=b.weights), atol=1e-12)


def test_sir_resamples_on_acceptance_and_spreads_on_a_miss():
    rng = np.random.default_rng(5)
    f, tr = SirPF(), track()
    f.restart(tr, 300, rng)
    w = np.zeros(300)
    w[:3] = 1 / 3
    f.accepted(tr, tr.particles, w, 0.0, rng)
    assert len(np.unique(tr.particles[:, 0])) <= 3 and np.allclose(tr.weights, 1 / 300)
    f.restart(tr, 300, rng)
    before = np.var(tr.particles[:, 0])
    tr.cov = tr.cov * 4.0
    f.missed(tr, 2.0)      # widened covariance 4x the particles': the inflation 2 binds
    assert np.var(tr.particles[:, 0]) == pytest.approx(2.0 * before, rel=1e-9)


def test_ekf_predicts_like_kalman_and_wraps_bearing_innovations():
    f = Ekf(np.diag([0.15 ** 2, math.radians(1.0) ** 2]), 9.21)
    tr = track(mean=(-10.0, 0.001, 0.0, 0.0))
    f.predict([tr], 1.0, 0.01, 0, None)
    assert tr.cov[0, 2] > 0                          # position and velocity now correlated
    # A region just across the +-pi cut: the innovation is small, not 2 pi.
    z = np.array([[10.0, -math.pi + 0.001]])
    H, S_inv, nu = f.innovations(tr, z, (0.0, 0.0, 0.0))
    assert abs(nu[0, 1]) < 0.01 and nu[0, 0] == pytest.approx(0.0, abs=0.01)
    before = tr.cov[0, 0]
    far = np.array([[-10.0, 5.0]])                   # outside the gate: no pair, no update
    assert f.update_on_regions([tr], far, (0.0, 0.0, 0.0)) == {} and tr.cov[0, 0] == before
    # The same region as a position, beside the far one: paired and updated across the cut.
    xy = np.array([[-10.0, 5.0], [10.0 * math.cos(z[0, 1]), 10.0 * math.sin(z[0, 1])]])
    assert f.update_on_regions([tr], xy, (0.0, 0.0, 0.0)) == {0: 1}
    assert tr.cov[0, 0] < before and tr.mean[1] < 0.001

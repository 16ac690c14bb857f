"""IMM-JIPDA association: the factors against joint events enumerated by brute force, and the tracker."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig, innovations, ipda_update
from sonar_tracking.core.tracking import jipda as jipda_module
from sonar_tracking.core.tracking import tracker as tracker_module
from sonar_tracking.core.tracking.gating import gate_threshold
from sonar_tracking.core.tracking.jipda import association_factors, exact_factors, pair_likelihoods, track_clusters

PD, PG = 0.85, 0.99


def joint_events(valid):
    """Every assignment of tracks to distinct measurements (-1 = none), ``valid (T, N)`` bool."""
    n_tracks, n_meas = valid.shape
    for ev in itertools.product(*[[-1] + [i for i in range(n_meas) if valid[t, i]] for t in range(n_tracks)]):
        used = [i for i in ev if i >= 0]
        if len(used) == len(set(used)):
            yield ev


def brute_marginals(psi, L, pdpg):
    """Existence and P(t -> i) of every track from the JIPDA joint events (Musicki & Evans 2004)."""
    n_tracks, n_meas = L.shape
    exist, beta, total = np.zeros(n_tracks), np.zeros((n_tracks, n_meas)), 0.0
    for ev in joint_events(L > 0):
        w = math.prod(1 - psi[t] * pdpg if i < 0 else psi[t] * L[t, i] for t, i in enumerate(ev))
        total += w
        for t, i in enumerate(ev):
            if i < 0:
                exist[t] += w * psi[t] * (1 - pdpg) / (1 - psi[t] * pdpg)
            else:
                exist[t] += w
                beta[t, i] += w
    return exist / total, beta / total


def random_cluster(rng, n_tracks, n_meas, density=0.7):
    L = rng.exponential(3.0, (n_tracks, n_meas)) * (rng.random((n_tracks, n_meas)) < density)
    return rng.uniform(0.05, 0.99, n_tracks), L


def ipda_weights(psi, L, r, pdpg):
    """Existence and P(t -> i) of single-track IPDAs whose likelihood ratios are ``L r`` (eqs. 32-34, 40)."""
    s = (L * r).sum(axis=1)
    den = 1 - psi * pdpg + psi * s
    return psi * (1 - pdpg + s) / den, psi[:, None] * L * r / den[:, None]


def factors_dense(psi, L, pdpg, limit):
    t, i = np.nonzero(L)
    f = association_factors(t, i, psi[t] * L[t, i], 1 - psi * pdpg, limit)
    r = np.ones_like(L)
    r[t, i] = f.r
    return r, f


@pytest.mark.parametrize('seed', range(12))
def test_exact_factors_give_the_joint_event_marginals(seed):
    rng = np.random.default_rng(seed)
    psi, L = random_cluster(rng, int(rng.integers(2, 6)), int(rng.integers(1, 6)))
    pdpg = PD * PG
    r, _ = factors_dense(psi, L, pdpg, 8)
    exist, beta = ipda_weights(psi, L, r, pdpg)
    exist_bf, beta_bf = brute_marginals(psi, L, pdpg)
    np.testing.assert_allclose(exist, exist_bf, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(beta, beta_bf, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize('n_meas', [1, 3])
def test_two_track_closed_form_equals_joint_events(n_meas):
    rng = np.random.default_rng(n_meas)
    psi, L = random_cluster(rng, 2, n_meas, density=1.0)
    r, f = factors_dense(psi, L, PD * PG, 8)
    assert f.largest == 2
    exist, beta = ipda_weights(psi, L, r, PD * PG)
    exist_bf, beta_bf = brute_marginals(psi, L, PD * PG)
    np.testing.assert_allclose(exist, exist_bf, rtol=1e-12)
    np.testing.assert_allclose(beta, beta_bf, rtol=1e-12)


def test_clusters_of_one_size_batched_equal_one_by_one():
    rng = np.random.default_rng(9)
    w, u = rng.exponential(1.0, (5, 3, 4)) * (rng.random((5, 3, 4)) < 0.7), rng.uniform(0.1, 1.0, (5, 3))
    batched = exact_factors(w, u)
    for c in range(5):
        np.testing.assert_allclose(batched[c], exact_factors(w[c], u[c]), rtol=1e-14)


def test_batches_of_clusters_equal_one_cluster_at_a_time(monkeypatch):
    """Many three-track clusters with different numbers of shared detections: the batched recursion
    (padded to the batch's largest) equals one cluster per batch."""
    rng = np.random.default_rng(12)
    tracks, meas = [], []
    for c in range(20):
        n_m = int(rng.integers(1, 6))
        valid = rng.random((3, n_m)) < 0.7
        valid[:, 0] = True                                   # all three share detection 0: one cluster
        t, i = np.nonzero(valid)
        tracks.append(3 * c + t)
        meas.append(10 * c + i)
    track, meas = np.concatenate(tracks), np.concatenate(meas)
    weight, unassigned = rng.exponential(1.0, len(track)), rng.uniform(0.1, 1.0, 60)
    together = association_factors(track, meas, weight, unassigned, 8)
    monkeypatch.setattr(jipda_module, '_DP_CELLS', 1)
    alone = association_factors(track, meas, weight, unassigned, 8)
    assert together.clusters == 20 and together.largest == 3
    np.testing.assert_allclose(alone.r, together.r, rtol=1e-13)


def test_exact_factors_are_scale_free_and_handle_extreme_weights():
    rng = np.random.default_rng(3)
    w, u = rng.exponential(1.0, (4, 5)), rng.uniform(0.1, 1.0, 4)
    big = exact_factors(w * 1e150, u * 1e150)
    np.testing.assert_allclose(big, exact_factors(w, u), rtol=1e-12)
    assert np.isfinite(exact_factors(np.array([[1e300, 1.0], [1e-300, 1.0]]), np.array([1e-300, 1.0]))).all()


def test_single_and_separate_tracks_get_factor_one():
    # Tracks 0 and 1 validate disjoint measurements; track 2 none.
    t, i = np.array([0, 0, 1]), np.array([0, 1, 2])
    f = association_factors(t, i, np.array([0.5, 2.0, 1.0]), np.array([0.3, 0.3, 0.3]), 8)
    assert np.array_equal(f.r, np.ones(3)) and f.clusters == 0
    empty = association_factors(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0), np.array([0.5]), 8)
    assert empty.r.shape == (0,) and empty.largest == 0


def test_one_shared_measurement_is_the_other_tracks_miss_probability():
    psi, L, pdpg = np.array([0.9, 0.6]), np.array([[4.0], [2.0]]), PD * PG
    r, f = factors_dense(psi, L, pdpg, 8)
    q = psi * L[:, 0] / (1 - psi * pdpg + psi * L[:, 0])       # each track's IPDA P(takes the measurement)
    np.testing.assert_allclose(r[:, 0], [1 - q[1], 1 - q[0]], rtol=1e-14)
    assert (f.clusters, f.largest, f.approximated) == (1, 2, 0)


def test_cluster_at_the_limit_is_exact_and_above_it_approximated():
    rng = np.random.default_rng(5)
    psi, L = random_cluster(rng, 6, 6, density=0.6)
    L[:, 0] = 1.0                                                 # one measurement every track validates
    pdpg = PD * PG
    exact, f_at = factors_dense(psi, L, pdpg, 6)
    assert (f_at.largest, f_at.approximated) == (6, 0)
    approx, f_above = factors_dense(psi, L, pdpg, 5)
    assert f_above.approximated == 1
    exist_bf, beta_bf = brute_marginals(psi, L, pdpg)
    np.testing.assert_allclose(ipda_weights(psi, L, exact, pdpg)[0], exist_bf, rtol=1e-12)
    exist_lm, beta_lm = ipda_weights(psi, L, approx, pdpg)
    assert np.isfinite(approx).all() and (approx > 0).all() and (approx <= 1).all()
    # LM-IPDA counts the other tracks' claims as independent: close, not equal (0.079 and 0.109 here).
    assert np.max(np.abs(exist_lm - exist_bf)) < 0.1
    assert np.max(np.abs(beta_lm - beta_bf)) < 0.15
    assert not np.allclose(exist_lm, exist_bf, rtol=1e-6)


def test_two_track_clusters_above_the_limit_are_still_exact():
    psi, L, pdpg = np.array([0.7, 0.8]), np.array([[1.0, 3.0, 0.0], [2.0, 0.5, 1.0]]), PD * PG
    approx, f = factors_dense(psi, L, pdpg, 1)
    assert f.approximated == 1
    np.testing.assert_allclose(approx, factors_dense(psi, L, pdpg, 8)[0], rtol=1e-12)


def test_clusters_are_connected_components():
    labels = track_clusters(np.array([0, 1, 1, 2, 3]), np.array([0, 0, 1, 2, 1]), 5, 3)
    assert labels[0] == labels[1] == labels[3] and len({labels[0], labels[2], labels[4]}) == 3
    # A chain in scrambled order (track k and k+1 share one measurement) is one component.
    rng = np.random.default_rng(0)
    perm = rng.permutation(3000)
    t = np.concatenate((perm[:-1], perm[1:]))
    m = np.concatenate((np.arange(2999), np.arange(2999)))
    order = np.argsort(t, kind='stable')
    chain = track_clusters(t[order], m[order], 3001, 2999)
    assert np.all(chain[:3000] == 0) and chain[3000] == 3000


def test_jipda_ipda_update_equals_joint_events_with_imm_modes():
    """Mode probabilities, mode means and existence of ipda_update with rho / r against the joint
    events enumerated with the modes of every track (eqs. 28-35 per joint event)."""
    rng = np.random.default_rng(21)
    n_tracks, n_modes, n_meas = 3, 2, 4
    x = rng.normal(0, 3, (4, n_modes, n_tracks))
    A = rng.normal(0, 1, (4, 4, n_modes, n_tracks))
    P = np.einsum('ikmt,jkmt->ijmt', A, A) + 4 * np.eye(4)[:, :, None, None]
    mu = rng.dirichlet(np.ones(n_modes), n_tracks).T
    psi = rng.uniform(0.2, 0.95, n_tracks)
    z = rng.normal(0, 3, (n_meas, 2))
    R = np.broadcast_to(np.eye(2), (n_meas, 2, 2))
    rho = rng.uniform(1e-3, 1e-2, n_meas)
    gamma = gate_threshold(PG)
    pt, pm = np.repeat(np.arange(n_tracks), n_meas), np.tile(np.arange(n_meas), n_tracks)
    innov = innovations(z[pm].T, R[pm].transpose(1, 2, 0), x[:2][:, :, pt], P[:2, :2][:, :, :, pt])
    in_gate = innov.d2 < gamma
    keep = in_gate.any(axis=0)
    pt, pm, innov, in_gate = pt[keep], pm[keep], innov.select(keep), in_gate[:, keep]
    assert len(pt) >= n_tracks + 2
    like = pair_likelihoods(mu, pt, innov, in_gate, rho[pm], PD, PG)
    f = association_factors(pt, pm, psi[pt] * like, 1 - psi * PD * PG, 8)
    assert f.clusters == 1
    res = ipda_update(x, P, mu, psi, pt, innov, in_gate, rho[pm] / f.r, PD, PG)

    # Brute force: p^m_{t,i} and the Kalman means per (track, mode, measurement), written out.
    pmode = np.zeros((n_tracks, n_modes, n_meas))
    xk = np.zeros((n_tracks, n_modes, n_meas, 4))
    H = np.eye(2, 4)
    for t in range(n_tracks):
        for m in range(n_modes):
            for i in range(n_meas):
                S = H @ P[:, :, m, t] @ H.T + R[i]
                nu = z[i] - H @ x[:, m, t]
                d2 = nu @ np.linalg.solve(S, nu)
                if d2 < gamma:
                    pmode[t, m, i] = math.exp(-0.5 * d2) / (2 * math.pi * math.sqrt(np.linalg.det(S))) / PG
                xk[t, m, i] = x[:, m, t] + P[:, :, m, t] @ H.T @ np.linalg.solve(S, nu)
    p = np.einsum('tm,tmi->ti', mu.T, pmode)                         # eq. (29)
    L = PD * PG * p / rho
    exist, num_mu, num_x = np.zeros(n_tracks), np.zeros((n_tracks, n_modes)), np.zeros((n_tracks, n_modes, 4))
    total = 0.0
    for ev in joint_events(L > 0):
        w = math.prod(1 - psi[t] * PD * PG if i < 0 else psi[t] * L[t, i] for t, i in enumerate(ev))
        total += w
        for t, i in enumerate(ev):
            if i < 0:        # exists and missed: mode m weight mu^m (1 - P_D P_G)
                share = w * psi[t] / (1 - psi[t] * PD * PG)
                exist[t] += share * (1 - PD * PG)
                wm = share * mu[:, t] * (1 - PD * PG)
                num_mu[t] += wm
                num_x[t] += wm[:, None] * x[:, :, t].T
            else:            # t -> i: mode m weight mu^m P_D P_G p^m_i / rho_i
                share = w / L[t, i]
                exist[t] += w
                wm = share * mu[:, t] * PD * PG * pmode[t, :, i] / rho[i]
                num_mu[t] += wm
                num_x[t] += wm[:, None] * xk[t, :, i]
    np.testing.assert_allclose(res.existence, exist / total, rtol=1e-12)
    np.testing.assert_allclose(res.mu.T, num_mu / num_mu.sum(axis=1, keepdims=True), rtol=1e-12)
    np.testing.assert_allclose(res.x.transpose(2, 1, 0), num_x / num_mu[:, :, None], rtol=1e-12, atol=1e-12)


def config(method, **flat):
    return TrackerConfig.from_flat({'association.method': method, **flat})


def two_target_scans(rng, gap, n_scans=25, n_clutter=15):
    """Two targets ``gap`` m apart moving in parallel at 3 m/s, P_D 0.9, clutter over 400 m x 400 m."""
    out = []
    for k in range(n_scans):
        truth = np.array([[-100.0 + 3 * k, 0.0], [-100.0 + 3 * k, gap]])
        hits = truth[rng.random(2) < 0.9]
        hits = hits + rng.normal(0, 3.0, hits.shape)
        z = np.concatenate((hits, rng.uniform(-200, 200, (rng.poisson(n_clutter), 2))))
        out.append((float(k), z, np.broadcast_to(9.0 * np.eye(2), (len(z), 2, 2)), np.full(len(z), 1e-4)))
    return out


def test_well_separated_targets_track_exactly_as_ipda():
    scans = two_target_scans(np.random.default_rng(2), gap=1000.0, n_clutter=0)
    a, b = ImmIpdaTracker(config('ipda')), ImmIpdaTracker(config('jipda'))
    for scan in scans:
        assert np.array_equal(a.step(*scan), b.step(*scan))
    assert b.report.n_confirmed == 2 and b.report.clusters == 0


def test_no_measurements_and_empty_scans():
    trk = ImmIpdaTracker(config('jipda', **{'existence.initial': 0.5}))
    assert len(trk.step(0.0, np.zeros((0, 2)))) == 0
    trk.step(1.0, np.array([[0.0, 0.0], [5.0, 0.0]]))
    out = trk.step(2.0, np.zeros((0, 2)))
    assert len(out) == 2 and np.isfinite(out['existence']).all() and trk.report.n_pairs == 0


def test_close_targets_share_detections_and_jipda_differs():
    scans = two_target_scans(np.random.default_rng(4), gap=12.0)
    a, b = ImmIpdaTracker(config('ipda')), ImmIpdaTracker(config('jipda'))
    clusters, differs = 0, False
    for scan in scans:
        oa, ob = a.step(*scan), b.step(*scan)
        clusters += b.report.clusters
        differs |= not np.array_equal(oa, ob)
        assert np.isfinite(ob['x']).all() and np.all((ob['existence'] >= 0) & (ob['existence'] <= 1))
    assert clusters > 0 and differs


def test_jipda_chunked_equals_one_chunk(monkeypatch):
    scans = two_target_scans(np.random.default_rng(6), gap=10.0, n_clutter=60)
    ref = ImmIpdaTracker(config('jipda'))
    outs = [ref.step(*scan).copy() for scan in scans]
    monkeypatch.setattr(tracker_module, '_CHUNK_PAIRS', 40)
    chunked = ImmIpdaTracker(config('jipda'))
    for k, scan in enumerate(scans):
        out = chunked.step(*scan)
        assert np.array_equal(out['track_id'], outs[k]['track_id'])
        for f in ('x', 'y', 'vx', 'existence', 'cov_xx', 'mode_cv'):
            np.testing.assert_allclose(out[f], outs[k][f], rtol=1e-10, atol=1e-12)


def test_association_settings_are_validated():
    assert TrackerConfig().association.method == 'ipda'
    with pytest.raises(ConfigError):
        config('jpda')
    with pytest.raises(ConfigError):
        config('jipda', **{'association.max_cluster': 13})


def test_dense_clutter_stays_bounded_and_large_clusters_are_approximated():
    rng = np.random.default_rng(19)
    trk = ImmIpdaTracker(config('jipda', **{'track.max_pairs': 20_000}))
    approximated = 0
    for k in range(4):
        out = trk.step(float(k), rng.uniform(-500, 500, (3000, 2)), None, np.full(3000, 3e-3))
        approximated += trk.report.approximated_clusters
        assert trk.report.n_pairs <= 20_000 and np.isfinite(out['x']).all()
    assert approximated > 0 and trk.report.largest_cluster > 8

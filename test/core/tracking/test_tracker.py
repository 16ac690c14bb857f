"""The tracker end to end: exactness, consistency, manoeuvres, clutter, management and bad input."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from sonar_tracking.core.detection.conversion import convert_measurements
from sonar_tracking.core.records import TRACK_DTYPE
from sonar_tracking.core.timeline import TimeWentBack
from sonar_tracking.core.tracking import (
    ConstantVelocity,
    ImmIpdaTracker,
    Mode,
    TrackerConfig,
    TrackingInputError,
    white_noise_acceleration,
)
from sonar_tracking.sim.motion import ScriptedTrajectory
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY, SCENARIO2_SEGMENTS


def config(**flat) -> TrackerConfig:
    return TrackerConfig.from_flat(flat)


def cv_truth(rng, n_steps, q, dts, speed_max=15.0):
    """CV truth with continuous white-noise acceleration ``q``; velocity drawn from the init prior."""
    x = np.concatenate([rng.uniform(-500, 500, 2), rng.normal(0, speed_max / math.sqrt(3), 2)])
    out = [x]
    for dt in dts[:n_steps - 1]:
        F = ConstantVelocity(2).transition(dt)
        x = F @ x + rng.multivariate_normal(np.zeros(4), white_noise_acceleration(dt, q))
        out.append(x)
    return np.array(out)


R0 = np.array([[25.0, 6.0], [6.0, 16.0]])


def test_single_model_with_pd_1_and_no_clutter_is_the_kalman_filter():
    """Acceptance: P_D = 1, no clutter, one model: the update equals a plain Kalman filter to 1e-9."""
    rng = np.random.default_rng(20)
    q = 0.2
    cfg = config(**{'imm.models': 'cv', 'imm.noise_cv': q, 'detection.probability': 1.0,
                    'detection.gate_probability': 1.0, 'clutter.source': 'constant', 'clutter.density': 1e-9})
    trk = ImmIpdaTracker(cfg)
    dts = rng.uniform(0.5, 2.0, 60)                       # irregular scans
    truth = cv_truth(rng, 60, q, dts)
    t = 1000.0
    H = np.eye(2, 4)
    for k in range(60):
        R = R0 * rng.uniform(0.5, 2.0)
        z = truth[k, :2] + rng.multivariate_normal([0, 0], R)
        if k == 0:
            x, P = np.concatenate([z, [0.0, 0.0]]), trk.initial_covariance(R)
        else:
            t += dts[k - 1]
            F = ConstantVelocity(2).transition(dts[k - 1])
            x, P = F @ x, F @ P @ F.T + white_noise_acceleration(dts[k - 1], q)
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            x, P = x + K @ (z - H @ x), (np.eye(4) - K @ H) @ P
        out = trk.step(t, z[None], R[None])
        assert len(out) == 1 and out['track_id'][0] == 1
        xs, Ps = trk.estimates()
        np.testing.assert_allclose(xs[0], x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(Ps[0], P, rtol=1e-9, atol=1e-9)
    assert out['existence'][0] > 0.999 and out['confirmed'][0] == 1


def cluttered_scans(rng, n_scans, density, half=400.0, pd=0.9):
    truth = cv_truth(rng, n_scans, 0.05, np.ones(n_scans))
    scans = []
    for k in range(n_scans):
        n = rng.poisson(density * (2 * half) ** 2)
        zc = truth[k, :2] + rng.uniform(-half, half, (n, 2))
        zs = [zc]
        if rng.random() < pd:
            zs.insert(0, truth[k, :2] + rng.multivariate_normal([0, 0], R0)[None])
        z = np.concatenate(zs)
        scans.append((float(k), z, np.broadcast_to(R0, (len(z), 2, 2)).copy(),
                       density * rng.uniform(0.5, 2.0, len(z))))
    return truth, scans


def test_imm_of_identical_models_equals_the_single_model():
    rng = np.random.default_rng(21)
    _, scans = cluttered_scans(rng, 40, 1e-4)
    mode = Mode('cv', ConstantVelocity(2), 0.05)
    one = ImmIpdaTracker(config(), modes=(mode,))
    three = ImmIpdaTracker(config(), modes=(mode, mode, mode))
    for s in scans:
        a, b = one.step(*s), three.step(*s)
        assert np.array_equal(a['track_id'], b['track_id']) and np.array_equal(a['confirmed'], b['confirmed'])
        for f in ('x', 'y', 'vx', 'vy', 'existence', 'cov_xx', 'cov_xy', 'cov_yy', 'cov_vxvx', 'cov_vyvy'):
            np.testing.assert_allclose(b[f], a[f], rtol=1e-9, atol=1e-9, err_msg=f)
        np.testing.assert_allclose(b['mode_cv'], 1.0, rtol=1e-12)
    assert (a['confirmed'] == 1).any()


def test_nees_of_clutter_free_cv_runs_is_inside_the_95_percent_band():
    """Acceptance: average NEES over runs stays in the two-sided 95 % chi-square band.

    100 runs x 40 scans, CV truth with the filter's own process noise, P_D = 1, no clutter. For a
    consistent filter each scan's run-average falls in the band with probability 0.95; we ask
    for at least 85 % of the scans (the scans are correlated, so the count varies more than a
    binomial would) and for the grand mean within 4 +/- 0.3.
    """
    runs, n_steps, q = 100, 40, 0.3
    cfg = config(**{'imm.models': 'cv', 'imm.noise_cv': q, 'detection.probability': 1.0,
                    'detection.gate_probability': 0.999, 'clutter.source': 'constant', 'clutter.density': 1e-8})
    nees = np.full((runs, n_steps), np.nan)
    for run in range(runs):
        rng = np.random.default_rng(1000 + run)
        truth = cv_truth(rng, n_steps, q, np.ones(n_steps))
        trk = ImmIpdaTracker(cfg)
        for k in range(n_steps):
            trk.step(float(k), (truth[k, :2] + rng.multivariate_normal([0, 0], R0))[None], R0[None])
            ids = trk.tracks()['track_id']
            if ids.size and ids[0] == 1:
                xs, Ps = trk.estimates()
                e = truth[k] - xs[0]
                nees[run, k] = e @ np.linalg.solve(Ps[0], e)
    kept = ~np.isnan(nees).any(axis=1)
    assert kept.mean() >= 0.98, 'the track of the target must survive in (almost) every run'
    mean = np.nanmean(nees[kept], axis=0)
    n = kept.sum()
    lo, hi = stats.chi2.ppf(0.025, 4 * n) / n, stats.chi2.ppf(0.975, 4 * n) / n
    inside = (mean >= lo) & (mean <= hi)
    assert inside.mean() >= 0.85, (lo, hi, np.round(mean, 2))
    assert np.nanmean(nees[kept]) == pytest.approx(4.0, abs=0.3)


def scenario2_mode_probabilities(runs=20, pd=0.9, clutter_per_km2=75.0):
    """Scenario 2 (Table 2) truth, harbour sonar noise converted with eqs. 8-10, clutter around the target."""
    traj = ScriptedTrajectory(50.0, 200.0, 12.0, 0.0, SCENARIO2_SEGMENTS)
    sx, sy = HARBOUR_SONAR_XY
    density = clutter_per_km2 / 1e6
    cfg = config(**{'detection.probability': pd, 'clutter.source': 'constant', 'clutter.density': density})
    mu = np.full((runs, 101, 3), np.nan)
    for run in range(runs):
        rng = np.random.default_rng(2000 + run)
        trk = ImmIpdaTracker(cfg)
        for k in range(101):
            s = traj.state(float(k))
            r = math.hypot(s[0] - sx, s[1] - sy) + rng.normal(0, 5.0)
            b = math.atan2(s[1] - sy, s[0] - sx) + rng.normal(0, math.radians(0.1))
            z, R = convert_measurements(np.array([r]), np.array([b]), 5.0, math.radians(0.1), (sx, sy, 0.0))
            if rng.random() > pd:
                z, R = z[:0], R[:0]
            n = rng.poisson(density * 1e6)
            zc = s[:2] + rng.uniform(-500, 500, (n, 2))
            z = np.concatenate([z, zc])
            R = np.concatenate([R, np.broadcast_to(np.diag([25.0, 25.0]), (n, 2, 2))])
            out = trk.step(float(k), z, R)
            conf = out[out['confirmed'] == 1]
            if len(conf):
                d = np.hypot(conf['x'] - s[0], conf['y'] - s[1])
                if d.min() < 50:
                    i = np.argmin(d)
                    mu[run, k] = conf['mode_cv'][i], conf['mode_ccw'][i], conf['mode_cw'][i]
    return mu


def test_matching_mode_wins_by_the_middle_of_each_turn_of_scenario2():
    """Acceptance: Table 2 (CV 20 s, CCW 3 deg/s 30 s, CW 3 deg/s 30 s, CV 20 s), 20 seeded runs,
    P_D 0.9, clutter 75 per km^2: the matching mode's probability averages above 0.5 at the middle
    of each turn (t = 35 s and 65 s); it is also the most likely mode at the end of the final CV leg.
    """
    mu = scenario2_mode_probabilities()
    tracked = ~np.isnan(mu[:, :, 0])
    assert tracked[:, 35].mean() >= 0.9 and tracked[:, 65].mean() >= 0.9
    mean = {k: np.nanmean(mu[:, k], axis=0) for k in (35, 65, 99)}
    assert mean[35][1] > 0.5, mean[35]
    assert mean[65][2] > 0.5, mean[65]
    assert mean[99].argmax() == 0, mean[99]


def test_a_clutter_only_track_decays_and_is_terminated():
    """Acceptance: a track started on clutter loses existence and is terminated (30 seeded runs)."""
    density = 2e-4
    cfg = config(**{'existence.initial': 0.5, 'clutter.source': 'constant', 'clutter.density': density})
    lifetimes, existence = [], np.zeros((30, 31))
    for run in range(30):
        rng = np.random.default_rng(3000 + run)
        trk = ImmIpdaTracker(cfg)
        trk.step(0.0, np.zeros((1, 2)), R0[None])
        existence[run, 0] = 0.5
        life = None
        for k in range(1, 31):
            n = rng.poisson(density * 1000.0 ** 2)
            out = trk.step(float(k), rng.uniform(-500, 500, (n, 2)), np.broadcast_to(R0, (n, 2, 2)))
            row = out[out['track_id'] == 1]
            if len(row) == 0:
                life = k
                break
            existence[run, k] = row['existence'][0]
        lifetimes.append(life)
    assert all(life is not None for life in lifetimes), lifetimes
    mean = existence.mean(axis=0)
    assert mean[1] < 0.5 and mean[3] < mean[1] and mean[10] < 0.05


@pytest.mark.parametrize('exclude', ['confirmed', 'all'])
def test_one_target_gives_one_confirmed_track_and_duplicates_are_removed(exclude):
    """With the paper's initiation (exclude: confirmed) the target's detections start more tracks
    while its first is tentative and they are merged away; with exclude: all none are started."""
    rng = np.random.default_rng(22)
    truth, scans = cluttered_scans(rng, 30, 0.0, pd=1.0)
    trk = ImmIpdaTracker(config(**{'clutter.source': 'constant', 'clutter.density': 1e-5, 'init.exclude': exclude}))
    merged = initiated = 0
    for s in scans:
        out = trk.step(*s)
        merged += trk.report.merged
        initiated += trk.report.initiated
    conf = out[out['confirmed'] == 1]
    assert len(conf) == 1 and len(out) == 1
    assert math.hypot(conf['x'][0] - truth[-1, 0], conf['y'][0] - truth[-1, 1]) < 15
    if exclude == 'confirmed':
        assert merged > 0, 'tracks started while the first was tentative must have been merged away'
    else:
        assert merged == 0 and initiated == 1


def test_output_records():
    rng = np.random.default_rng(23)
    _, scans = cluttered_scans(rng, 15, 1e-4)
    trk = ImmIpdaTracker()
    for s in scans:
        out = trk.step(*s)
        assert out.dtype == TRACK_DTYPE
        np.testing.assert_allclose(out['mode_cv'] + out['mode_ccw'] + out['mode_cw'], 1.0, rtol=1e-12)
        assert np.all(np.diff(out['track_id'].astype(np.int64)) > 0)
        assert np.all((out['existence'] >= 0) & (out['existence'] <= 1))
        assert all(np.isfinite(out[f]).all() for f in TRACK_DTYPE.names)
        assert trk.report.n_tracks == len(out) and trk.report.n_confirmed == int(out['confirmed'].sum())


def test_track_ids_are_unique_for_the_trackers_life_across_resets():
    rng = np.random.default_rng(24)
    _, scans = cluttered_scans(rng, 20, 2e-4)
    trk = ImmIpdaTracker()
    seen: dict[int, float] = {}
    for loop in range(3):                          # a bag played three times: time jumps back twice
        for t, z, R, rho in scans:
            if t == 0.0 and loop:                  # refused, unchanged; the caller restarts the tracker
                before = (trk.time, trk.tracks().copy())
                with pytest.raises(TimeWentBack, match='scan at .* before the previous one'):
                    trk.step(t, z, R, rho)
                assert trk.time == before[0] and np.array_equal(trk.tracks(), before[1]) and len(before[1])
                trk.reset()
            out = trk.step(t, z, R, rho)
            for i in out['track_id'].tolist():
                seen.setdefault(i, loop)
                assert seen[i] == loop, f'track id {i} reused after a reset'


def test_duplicate_stamp_is_dropped_and_returns_the_previous_tracks():
    rng = np.random.default_rng(25)
    _, scans = cluttered_scans(rng, 5, 1e-4)
    trk = ImmIpdaTracker()
    for s in scans:
        out = trk.step(*s)
    again = trk.step(scans[-1][0], scans[0][1])
    assert trk.report.duplicate_stamp and np.array_equal(again, out)
    later = trk.step(scans[-1][0] + 1.0, scans[-1][1])
    assert not trk.report.duplicate_stamp and len(later)


def test_long_gap_restarts_the_tracker():
    trk = ImmIpdaTracker(config(**{'track.max_gap': 10.0}))
    trk.step(0.0, np.zeros((1, 2)))
    out = trk.step(100.0, np.ones((1, 2)))
    assert 'track.max_gap' in trk.report.reset and out['track_id'].tolist() == [2]


def test_bad_rows_are_dropped_with_reasons_and_the_rest_used():
    trk = ImmIpdaTracker()
    z = np.array([[0.0, 0.0], [np.nan, 1.0], [5.0, 5.0], [7.0, 7.0], [9.0, 9.0], [11.0, 11.0], [np.inf, 0.0]])
    R = np.broadcast_to(R0, (7, 2, 2)).copy()
    R[2] = [[1.0, 2.0], [2.0, 1.0]]            # not positive definite
    R[3] = [[1.0, 0.5], [0.4, 1.0]]            # not symmetric
    R[4, 0, 0] = np.nan
    rho = np.full(7, 1e-4)
    rho[5] = 0.0
    out = trk.step(0.0, z, R, rho)
    reasons = {r.index: r.reason for r in trk.report.rejected}
    assert sorted(reasons) == [1, 2, 3, 4, 5, 6]
    assert 'not finite' in reasons[1] and 'positive definite' in reasons[2] and 'symmetric' in reasons[3]
    assert 'covariance' in reasons[4] and 'clutter density' in reasons[5]
    assert len(out) == 1 and out['x'][0] == 0.0


def test_garbage_never_crashes_and_never_gives_nan():
    """Random garbage (NaN, inf, huge and tiny values, singular covariances) over many scans."""
    rng = np.random.default_rng(26)
    trk = ImmIpdaTracker(config(**{'clutter.source': 'detection'}))
    specials = np.array([np.nan, np.inf, -np.inf, 0.0, 1e-300, 1e300, -1e300, 1e12, -1e-12])
    t = 0.0
    for k in range(300):
        n = int(rng.integers(0, 30))
        z = rng.normal(0, 10.0 ** rng.integers(0, 7), (n, 2))
        R = np.broadcast_to(np.diag(10.0 ** rng.uniform(-6, 6, 2)), (n, 2, 2)).copy()
        rho = 10.0 ** rng.uniform(-12, 0, n)
        for arr in (z, R, rho):
            flat = arr.reshape(-1)
            hit = rng.random(flat.size) < 0.05
            flat[hit] = rng.choice(specials, hit.sum())
        t += float(rng.choice([1.0, 0.0, -3.0, 0.5, 1e-9, 1e4], p=[0.8, 0.05, 0.02, 0.1, 0.02, 0.01]))
        try:
            out = trk.step(t, z, R, rho)
        except TimeWentBack:        # the caller restarts, as the nodes do on a jump back
            trk.reset()
            out = trk.step(t, z, R, rho)
        for f in TRACK_DTYPE.names:
            assert np.isfinite(out[f]).all(), (k, f)


def test_shapes_that_do_not_fit_raise_with_the_expected_shape():
    trk = ImmIpdaTracker()
    with pytest.raises(TrackingInputError, match=r'\(N, d\)'):
        trk.step(0.0, np.zeros(3))
    with pytest.raises(TrackingInputError, match='R must have shape'):
        trk.step(0.0, np.zeros((2, 2)), np.zeros((3, 2, 2)))
    with pytest.raises(TrackingInputError, match='rho must have shape'):
        trk.step(0.0, np.zeros((2, 2)), None, np.zeros(3))
    with pytest.raises(TrackingInputError, match='columns'):
        trk.step(0.0, np.zeros((2, 3)))
    with pytest.raises(TrackingInputError, match='not finite'):
        trk.step(math.nan, np.zeros((1, 2)))
    assert len(trk.step(0.0, np.zeros((0, 2)))) == 0


def test_constant_clutter_source_ignores_detection_densities():
    z = np.array([[0.0, 0.0]])
    a = ImmIpdaTracker(config(**{'clutter.source': 'constant', 'clutter.density': 1e-4}))
    b = ImmIpdaTracker(config(**{'clutter.source': 'constant', 'clutter.density': 1e-4}))
    for k in range(5):
        ra, rb = a.step(float(k), z + k, None, [1e-9]), b.step(float(k), z + k, None, [5.0])
    assert np.array_equal(ra, rb)


def test_cap_on_tracks_drops_the_least_likely_tentative_ones():
    rng = np.random.default_rng(27)
    trk = ImmIpdaTracker(config(**{'track.max_tracks': 50}))
    for k in range(5):
        out = trk.step(float(k), rng.uniform(-1000, 1000, (200, 2)))
    assert len(out) <= 50 + 200 and trk.report.capped > 0


def test_reconfiguring_keeps_tracks_unless_the_modes_change():
    trk = ImmIpdaTracker()
    trk.step(0.0, np.zeros((3, 2)) + np.arange(3)[:, None] * 100)
    assert not trk.configure(config(**{'detection.probability': 0.8}))
    assert trk.n_tracks == 3
    assert trk.configure(config(**{'imm.models': 'cv'}))
    assert trk.n_tracks == 0
    out = trk.step(1.0, np.zeros((1, 2)))
    assert out['track_id'].tolist() == [4] and out['mode_cv'][0] == 1.0

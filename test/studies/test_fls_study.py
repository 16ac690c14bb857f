"""The FLS study's scoring on hand-made tracks (owner, CLE eq. 19, lost frames, identity through a
crossing), summarise, the switch calibration, determinism across processes, and a seeded crossing
study as a regression guard."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.records import GPF_TRACK_DTYPE
from sonar_tracking.studies.fls_frames import TrackingFrame
from sonar_tracking.studies.fls_study import (
    crossing_window,
    paired_difference,
    parse_methods,
    run_cle,
    score_run,
    situation_scenario,
    summarise,
    switch_thresholds,
)

GATE, CROSS = 1.5, 2.0


def frames_of(paths: np.ndarray) -> list[TrackingFrame]:
    """Frames with targets at ``paths (F, G, 2)`` (no image: scoring only reads the truth)."""
    n_f, g = paths.shape[:2]
    out = []
    for k in range(n_f):
        truth = np.zeros((g, 4))
        truth[:, :2] = paths[k]
        out.append(TrackingFrame(None, np.arange(1, g + 1), truth, np.full(g, 5.0 * k)))
    return out


def recs(*tracks) -> np.ndarray:
    """GPF_TRACK_DTYPE records of ``(track_id, x, y)``."""
    r = np.zeros(len(tracks), GPF_TRACK_DTYPE)
    for i, (tid, x, y) in enumerate(tracks):
        r[i]['track_id'], r[i]['x'], r[i]['y'] = tid, x, y
    return r


def crossing_paths(n: int = 11) -> np.ndarray:
    """Two targets on an X: (10, -4) -> (20, 4) and (20, -4) -> (10, 4), crossing at frame n // 2."""
    s = np.linspace(0.0, 1.0, n)
    a = np.column_stack([10 + 10 * s, -4 + 8 * s])
    b = np.column_stack([20 - 10 * s, -4 + 8 * s])
    return np.stack([a, b], axis=1)


def test_owner_is_the_first_track_within_the_gate_and_is_kept_while_it_exists():
    paths = np.zeros((5, 1, 2))
    fr = frames_of(paths)
    records = [recs(),                                  # no track: no owner, lost
               recs((5, 1.0, 0.0), (7, 3.0, 0.0)),      # 5 within the gate, 7 not
               recs((7, 0.1, 0.0), (5, 1.2, 0.0)),      # 7 is nearer, 5 keeps the target
               recs((7, 0.1, 0.0), (5, 0.0, 2.0)),      # 5 off by 2 m: still the owner, a lost frame
               recs((7, 0.0, 0.3))]                     # 5 ended: 7 takes over (a new identity)
    s = score_run(fr, records, GATE, CROSS)
    cle = s['cle'][0]
    assert math.isnan(cle[0])
    np.testing.assert_allclose(cle[1:], [1.0, 1.2, 2.0, 0.3])     # eq. (19): Euclidean distance
    assert s['lost'][0].tolist() == [True, False, False, True, False]
    np.testing.assert_allclose(s['capped'][0], [GATE, 1.0, 1.2, GATE, 0.3])
    assert s['acquisitions'].tolist() == [2]
    assert s['identity'] is None                        # one target: nothing crosses


def test_targets_get_distinct_owners_by_least_distance():
    paths = np.array([[[0.0, 0.0], [0.0, 1.0]]])
    s = score_run(frames_of(paths), [recs((1, 0.0, 0.9), (2, 0.0, 0.2))], GATE, CROSS)
    np.testing.assert_allclose(s['cle'][:, 0], [0.2, 0.1])


def test_crossing_window():
    paths = crossing_paths()
    before, after = crossing_window(frames_of(paths), CROSS)
    d = np.linalg.norm(paths[:, 0] - paths[:, 1], axis=1)
    assert d[before] >= CROSS and d[before + 1] < CROSS
    assert d[after] >= CROSS and d[after - 1] < CROSS
    parallel = np.stack([paths[:, 0], paths[:, 0] + [0.0, 5.0]], axis=1)
    assert crossing_window(frames_of(parallel), CROSS) is None


def test_identity_kept_through_the_crossing_and_lost_by_a_swap():
    paths = crossing_paths()
    fr = frames_of(paths)
    follow = [recs((1, *p[0] + 0.1), (2, *p[1] - 0.1)) for p in paths]
    s = score_run(fr, follow, GATE, CROSS)
    assert s['identity'].tolist() == [1.0, 1.0]
    assert not s['lost'].any()
    _, after = crossing_window(fr, CROSS)
    swap = [recs((1, *p[0]), (2, *p[1])) if k < after else recs((1, *p[1]), (2, *p[0]))
            for k, p in enumerate(paths)]
    s = score_run(fr, swap, GATE, CROSS)
    assert s['identity'].tolist() == [0.0, 0.0]
    assert np.all(s['cle'][:, after:] > GATE)           # each owner now follows the other target
    late = [recs() if k < after else recs((1, *p[0])) for k, p in enumerate(paths)]
    s = score_run(fr, late, GATE, CROSS)
    assert np.isnan(s['identity']).all()                # no owner before: says nothing about identity


def _run(cle, identity):
    cle = np.asarray(cle, dtype=float)
    lost = np.isnan(cle) | (cle > GATE)
    return {'scores': {'af': {'cle': cle, 'lost': lost, 'capped': np.where(lost, GATE, cle),
                              'acquisitions': np.ones(cle.shape[0], np.int64),
                              'identity': None if identity is None else np.asarray(identity, float)}},
            'corrections': {'af': np.array([2, 1, 1])}}


def test_summarise_means_lost_frames_and_identity_rate():
    class Study:
        methods = ('af',)
    runs = [_run([[0.2, np.nan, 0.4], [0.1, 0.1, 0.1]], [1.0, 1.0]),
            _run([[0.6, 2.0, np.nan], [0.3, 0.3, 0.3]], [0.0, 1.0]),
            _run([[np.nan] * 3, [0.2, 0.2, 0.2]], [np.nan, np.nan])]
    r = summarise(Study, runs)['af']
    assert r['cle_mean'] == pytest.approx([(0.2 + 0.4 + 0.6 + 2.0) / 4, 0.2])
    assert r['cle'][0] == pytest.approx([0.4, 2.0, 0.4]) and len(r['cle']) == 2
    assert r['lost_frames'] == pytest.approx([(1 + 2 + 3) / 3, 0.0])
    assert r['identity_runs'] == 2 and r['identity_kept_rate'] == pytest.approx(0.5)
    assert r['identity_kept_rate_per_target'] == pytest.approx([0.5, 1.0])
    # Track-frames by what corrected them, summed over the runs.
    assert r['corrections'] == {'image': 6, 'region': 3, 'coasting': 3, 'image_share': pytest.approx(6 / 9)}


def test_run_cle_averages_targets_over_their_defined_frames():
    assert run_cle(np.array([[0.2, np.nan, 0.4], [1.0, 1.0, 1.0]])) == pytest.approx((0.3 + 1.0) / 2)
    assert run_cle(np.array([[np.nan, np.nan], [0.5, 0.7]])) == pytest.approx(0.6)
    assert math.isnan(run_cle(np.full((2, 3), np.nan)))


def test_paired_difference_mean_and_student_t_interval():
    a = np.array([1.0, 2.0, 3.0, np.nan, 5.0])
    b = np.array([0.5, 2.5, 2.0, 1.0, np.nan])
    p = paired_difference(a, b)                         # runs 0-2: differences 0.5, -0.5, 1.0
    assert p['runs'] == 3 and p['difference'] == pytest.approx(1.0 / 3)
    sd = np.std([0.5, -0.5, 1.0], ddof=1)
    assert p['ci95'] == pytest.approx(4.302652729911275 * sd / math.sqrt(3))   # t(0.975, 2 dof)
    assert paired_difference(np.array([1.0]), np.array([0.5])) == {'difference': 0.5, 'ci95': None, 'runs': 1}
    assert paired_difference(np.array([np.nan]), np.array([0.5]))['difference'] is None


def test_summarise_pairs_every_method_with_the_first_run_by_run():
    class Study:
        methods = ('af', 'wf')
    runs = []
    for af, wf in ((0.3, 0.4), (0.5, 0.5), (0.2, 0.6)):
        r = _run([[af, af]], None)
        r['scores']['wf'] = _run([[wf, wf]], None)['scores']['af']
        r['corrections']['wf'] = np.array([0, 3, 1])
        runs.append(r)
    out = summarise(Study, runs)
    assert out['af']['cle_run'] == pytest.approx([0.3, 0.5, 0.2]) and 'paired_with_first' not in out['af']
    p = out['wf']['paired_with_first']
    assert p['first'] == 'af' and p['runs'] == 3 and p['difference'] == pytest.approx((-0.1 + 0.0 - 0.4) / 3)


def test_switch_thresholds_meet_the_healthy_mf_rate():
    rng = np.random.default_rng(11)
    samples = rng.lognormal(0.0, 0.1, (4000, 5)) * np.array([1.0, 1.2, 0.9, 1.5, 1.0])
    t, p = switch_thresholds(samples, 0.75)
    rate = np.mean(np.all(samples > t, axis=1))
    assert rate == pytest.approx(0.75, abs=0.01)
    assert 0.0 < p < 25.0                               # independent cues: about 1 - 0.75 ** (1 / 5)
    np.testing.assert_allclose(t, np.percentile(samples, p, axis=0))
    with pytest.raises(ValueError):
        switch_thresholds(np.zeros((0, 5)))


def test_af18_is_eq_18_alone_and_af_keeps_the_crossing_switch():
    from sonar_tracking.studies.fls_study import FlsStudy, _tracker
    study = FlsStudy('fls8')
    af, af18 = (_tracker(study, m, np.random.default_rng(0)).config.fusion for m in ('af', 'af18'))
    assert (af.mode, af.switch) == ('af', 'crossing') and (af18.mode, af18.switch) == ('af', 'cues')


def test_each_method_confirms_with_its_own_setting_inside_the_run_and_only_confirmed_tracks_score():
    """``confirm_by_method`` builds each tracker with its own ``birth.confirm_hits`` (recorded per run
    from the tracker's configuration); with ``score_confirmed`` an EKF that needs four hits has no
    confirmed track in the first three frames, so GOSPA there is the two missed targets' (c), while
    scoring every track sees its tentative ones."""
    from dataclasses import replace

    from sonar_tracking.studies.fls_study import FlsStudy, run_once
    from sonar_tracking.studies.fls_table import GOSPA
    study = FlsStudy('fls8', methods=('ekf', 'af'), gospa=GOSPA, confirm_by_method=(('ekf', 4), ('af', 1)))
    seed = np.random.SeedSequence(3).spawn(1)[0]
    confirmed, every = run_once(replace(study, score_confirmed=True), seed), run_once(study, seed)
    assert confirmed['confirm'] == {'ekf': 4, 'af': 1}
    np.testing.assert_allclose(confirmed['gospa']['ekf'][:3], GOSPA.c)
    assert every['gospa']['ekf'][0] < GOSPA.c
    np.testing.assert_array_equal(confirmed['gospa']['af'], every['gospa']['af'])   # one hit: all confirmed


def test_corrections_of_a_frame_from_the_tracker_report():
    from sonar_tracking.studies.fls_study import _corrections
    assert _corrections(seen=4, missed=3, reseeded=2, regions_only=False) == (4, 2, 1)
    assert _corrections(seen=4, missed=3, reseeded=0, regions_only=True) == (0, 4, 3)


def test_methods_and_situations():
    assert parse_methods('af, ekf') == ('af', 'ekf')
    for bad in ('af,magic', '', 'af,af'):
        with pytest.raises(ValueError):
            parse_methods(bad)
    assert situation_scenario(8) == 'fls8' and situation_scenario('sea-trial') == 'sea_trial'
    with pytest.raises(ValueError):
        situation_scenario(15)


def test_results_do_not_depend_on_the_number_of_processes():
    from sonar_tracking.cli.fls_eval import run_study, study_for
    study = study_for(8, None, ('af', 'ekf'))
    one = run_study(study, 2, 5, jobs=1)
    two = run_study(study, 2, 5, jobs=2)
    assert one['methods'] == two['methods']
    assert one['example'] == two['example']


def test_methods_share_the_random_stream_so_equal_decisions_give_equal_tracks():
    """Common random numbers: AF that always chooses WF (thresholds no cue can reach) tracks exactly
    as WF does; MF, deciding differently, does not."""
    from sonar_tracking.core.gpf import GpfConfig
    from sonar_tracking.studies.fls_frames import simulate_tracking_frames
    from sonar_tracking.studies.fls_study import FlsStudy, run_methods
    frames = simulate_tracking_frames('fls8', 3)[:6]
    study = FlsStudy('fls8', ('af', 'mf', 'wf'), GpfConfig.from_flat({'fusion.thresholds': (1e6,)}))
    out = run_methods(study, frames, np.random.SeedSequence(11))
    assert any(len(r) for r in out['wf'])
    for a, w in zip(out['af'], out['wf']):
        np.testing.assert_array_equal(a, w)
    assert any(len(a) != len(m) or not np.array_equal(a, m) for a, m in zip(out['af'], out['mf']))


def test_crossing_adaptive_fusion_keeps_identity_and_beats_multiplicative():
    """Regression guard for the crossing criterion on situation 8, where AF's lead is clear of the
    noise (1000 runs, seed 4000: AF - WF -0.017 +/- 0.007 m, AF - MF -0.071 +/- 0.027 m): in 16 seeded
    runs AF keeps identity in at least 80 % of them, has a lower mean CLE than MF and is within 0.05 m
    of WF (the spread of a 16-run set, not a claim that it is behind; this seed gives AF / MF / WF
    0.345 / 0.786 / 0.372 m and identity 100 / 75 / 100 %)."""
    from sonar_tracking.cli.fls_eval import run_study, study_for
    out = run_study(study_for(8, None, ('af', 'mf', 'wf')), 16, 2026, jobs=1)['methods']
    cle = {m: float(np.mean(out[m]['cle_mean'])) for m in ('af', 'mf', 'wf')}
    assert out['af']['identity_kept_rate'] >= 0.8
    assert cle['af'] < cle['mf']
    assert cle['af'] < cle['wf'] + 0.05

"""Tracking bench cases: registered as the issue asks, identical seeded detections, Stone Soup optional.

Structure only: no timing is asserted here (timing lives in ``sonar_eval bench``).
"""
from __future__ import annotations

import math
import sys

import numpy as np

from sonar_tracking.cli import bench
from sonar_tracking.cli.bench_cases import tracking


def test_cases_limits_and_baselines():
    cases = bench.cases()
    for n in tracking.CLUTTER:
        c = cases[f'tracking.imm_ipda.c{n}']
        assert c.self_timed and c.group == 'tracking'
        # Stone Soup beside every clutter row it can finish (10,000 would take hours a scan)
        assert c.compare_to == (f'tracking.stonesoup.c{n}' if n < 10000 else None)
    for k in tracking.TARGETS:
        assert cases[f'tracking.imm_ipda.t{k}'].compare_to == (f'tracking.stonesoup.t{k}' if k > 1 else None)
    assert cases['tracking.imm_ipda.c20'].limit_s == 0.35e-3
    assert cases['tracking.imm_ipda.c10000'].limit_s == 0.1
    assert cases['tracking.imm_ipda.t200'].limit_s == 3e-3
    assert cases[f'tracking.imm_ipda.flood{tracking.FLOOD}'].self_timed
    for tag, n_clutter, n_targets, _, _ in tracking.STONESOUP:
        assert f'tracking.stonesoup.{tag}' in cases
        assert tag == (f'c{n_clutter}' if n_targets == 1 else f't{n_targets}')


def test_detections_are_seeded_and_shared():
    a, b = tracking.scans(50, 30), tracking.scans(50, 30)
    for (ta, za, Ra, ra), (tb, zb, Rb, rb) in zip(a, b):
        assert ta == tb and np.array_equal(za, zb) and np.array_equal(Ra, Rb) and np.array_equal(ra, rb)
    counts = [len(z) for _, z, _, _ in tracking.scans(400, 100)]
    assert 380 < np.mean(counts) < 420 and np.allclose(a[0][3], 50 / 1e6)
    many = tracking.scans(0, 20, n_targets=50)
    assert 40 < np.mean([len(z) for _, z, _, _ in many]) < 50          # P_D 0.9, no clutter
    z = many[0][1]
    assert np.all(np.abs(z) < tracking.HALF) and len(np.unique(np.round(z, 6), axis=0)) == len(z)


def test_growth_exponent_from_the_previous_size():
    tracking._STEPPERS['test.big'] = tracking._STEPPERS['test.small'] = type('S', (), {'tracks': [1]})()
    small = bench.Result(name='test.small', group='tracking', description='', median_s=1e-3, p25_s=0, p75_s=0,
                         min_s=0, max_s=0, repeats=1, number=1)
    tracking._derived('test.small', 10)(small)
    big = bench.Result(**{**small.__dict__, 'name': 'test.big', 'median_s': 4e-3})
    assert math.isclose(tracking._derived('test.big', 40, 'test.small', 4.0)(big)['growth'], 1.0)


def test_flood_child_reports_times_and_memory(capsys):
    tracking.flood_child(3000, 3)
    import json
    got = json.loads(capsys.readouterr().out)
    assert len(got['seconds']) == 3 and got['peak_rss_mb'] > 0
    assert got['max_tracks'] <= 5000 and 0 < got['max_pairs'] <= 100_000


def test_our_case_steps_one_scan_per_call():
    fn = tracking._ours(20, 'test.ours')()
    seconds = [fn() for _ in range(3)]
    assert all(s > 0 for s in seconds) and len(tracking._STEPPERS['test.ours'].tracks) == 3


def test_stonesoup_missing_is_reported_not_failed(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, 'stonesoup', None)          # import stonesoup -> ImportError
    fn = tracking._stonesoup(20, 'tracking.stonesoup.test', 1)()
    assert math.isnan(fn())
    assert 'stonesoup not installed' in capsys.readouterr().err
    case = bench.Case(name='tracking.stonesoup.test', group='tracking', make=lambda: fn, self_timed=True, repeats=2,
                      derived=tracking._derived('tracking.stonesoup.test', 20))
    result = bench.run_case(case)
    assert 'stonesoup not installed' in result.extra['note']


def test_pair_cases_share_detections_and_baselines():
    cases = bench.cases()
    for k in tracking.PAIRS:
        assert cases[f'tracking.imm_jipda.pairs{k}'].compare_to == f'tracking.stonesoup_jpda.pairs{k}'
        assert cases[f'tracking.imm_ipda.pairs{k}'].compare_to == f'tracking.imm_jipda.pairs{k}'
    assert [len(z) for _, z, _, _ in tracking.scans(20, 30, n_targets=10)] == \
        [len(z) for _, z, _, _ in tracking.scans(20, 30, n_targets=10, pair_gap=15.0)]
    z = tracking.scans(0, 1, seed=3, n_targets=10, pair_gap=15.0)[0][1]
    gaps = np.hypot(*(z[:, None] - z[None]).transpose(2, 0, 1))
    np.fill_diagonal(gaps, np.inf)
    assert np.median(gaps.min(axis=1)) < 40.0           # each target has its partner close by


def test_jipda_case_steps_and_clusters_form():
    fn = tracking._ours(20, 'test.jipda', n_targets=2, n_scans=60, association='jipda', pair_gap=15.0)()
    assert all(fn() > 0 for _ in range(3))
    assert tracking._STEPPERS['test.jipda'].tracker.config.association.method == 'jipda'

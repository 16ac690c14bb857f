"""Tracking bench cases: registered as the issue asks, identical seeded detections, Stone Soup optional.

Structure only: no timing is asserted here (timing lives in ``sonar_eval bench``).
"""
from __future__ import annotations

import math
import sys

import numpy as np

from sonar_tracking.tools import bench
from sonar_tracking.tools.bench_cases import tracking


def test_cases_limits_and_baselines():
    cases = bench.cases()
    for key in [f't{n}' for n in tracking.TARGETS] + [f'c{n}' for n in tracking.CLUTTER]:
        c = cases[f'tracking.imm_ipda.{key}']
        assert c.self_timed and c.group == 'tracking'
        assert c.compare_to == (f'tracking.stonesoup.{key}' if key in tracking.STONESOUP else None)
        assert c.limit_s == tracking.LIMITS.get(key)
    assert tracking.LIMITS == {'t1': 0.35e-3, 't200': 3e-3, 'c10000': 0.1}
    for key in tracking.STONESOUP:
        assert f'tracking.stonesoup.{key}' in cases
    assert cases['tracking.imm_ipda.d20000'].self_timed


def test_detections_are_seeded_and_shared():
    a, b = tracking.scans(50, 30), tracking.scans(50, 30)
    for (ta, za, Ra, ra), (tb, zb, Rb, rb) in zip(a, b):
        assert ta == tb and np.array_equal(za, zb) and np.array_equal(Ra, Rb) and np.array_equal(ra, rb)
    counts = [len(z) for _, z, _, _ in tracking.scans(400, 100)]
    assert 380 < np.mean(counts) < 420 and np.allclose(a[0][3], 50 / 1e6)
    many = tracking.scans(0, 50, n_targets=200)
    assert 170 < np.mean([len(z) for _, z, _, _ in many]) < 190          # P_D 0.9 of 200 targets


def test_growth_exponent_is_the_log_log_slope_from_the_previous_row():
    assert tracking._series_previous('t1') is None and tracking._series_previous('c100') is None
    prev = tracking._series_previous('c10000')
    assert prev == ('tracking.imm_ipda.c1000', 1000.0, 10000.0)
    tracking._STEPPERS['test.growth'] = type('S', (), {'tracks': [1]})()
    tracking._MEDIANS['tracking.imm_ipda.c1000'] = 1e-3
    r = bench.Result(name='test.growth', group='tracking', description='', median_s=1e-2, p25_s=0, p75_s=0, min_s=0,
                     max_s=0, repeats=1, number=1)
    assert tracking._derived('test.growth', 10000, prev)(r)['growth'] == 1.0


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

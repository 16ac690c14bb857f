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
    for n in tracking.CLUTTER:
        c = cases[f'tracking.imm_ipda.c{n}']
        assert c.self_timed and c.group == 'tracking'
        assert c.compare_to == (f'tracking.stonesoup.c{n}' if n in tracking.STONESOUP else None)
    assert cases['tracking.imm_ipda.c20'].limit_s == 0.5e-3
    assert cases['tracking.imm_ipda.c400'].limit_s == 5e-3
    for n in tracking.STONESOUP:
        assert f'tracking.stonesoup.c{n}' in cases


def test_detections_are_seeded_and_shared():
    a, b = tracking.scans(50, 30), tracking.scans(50, 30)
    for (ta, za, Ra, ra), (tb, zb, Rb, rb) in zip(a, b):
        assert ta == tb and np.array_equal(za, zb) and np.array_equal(Ra, Rb) and np.array_equal(ra, rb)
    counts = [len(z) for _, z, _, _ in tracking.scans(400, 100)]
    assert 380 < np.mean(counts) < 420 and np.allclose(a[0][3], 50 / 1e6)


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

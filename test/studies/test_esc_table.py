"""The operating point of the ESC table: T_c per method from the CFT-scan rate of Table 1."""
from __future__ import annotations

import numpy as np
import pytest

from sonar_tracking.studies.confirmation import T_GRID, ConfirmationSweep
from sonar_tracking.studies.esc_study import StudyConfig, parse_methods
from sonar_tracking.studies.esc_table import operating_point


def synthetic_runs(n_runs: int, scans: int, false_until: dict, ctt: dict) -> list[dict]:
    """Per method: a false track confirmed in every scan of run 0 for T below ``false_until``
    (two of them, so the two counts differ), a true track in every scan of the runs listed."""
    runs = []
    for i in range(n_runs):
        run = {}
        for name, t_false in false_until.items():
            nf = np.zeros((scans, len(T_GRID)), np.int32)
            if i == 0:
                nf[:, t_false > T_GRID] = 2
            has = np.zeros((scans, len(T_GRID)), bool)
            has[:, :] = i in ctt[name]
            run[name] = {'n_false_t': nf, 'has_ctt_t': has}
        runs.append(run)
    return runs


def test_t_c_is_the_smallest_that_meets_the_cft_scan_rate_and_both_counts_are_reported():
    study = StudyConfig(scans=10, methods=parse_methods('esc,fixed:4'))
    runs = synthetic_runs(4, 10, {'esc': 0.9, 'fixed:4': 0.995}, {'esc': {0, 1, 2, 3}, 'fixed:4': {0, 1}})
    # Run 0 has false tracks in every scan: rate 1/4 > 0.005 below the T where they stop.
    op = operating_point(study, runs)
    assert op['esc']['t_c'] == pytest.approx(0.90) and op['fixed:4']['t_c'] == pytest.approx(T_GRID[T_GRID >= 0.995][0])
    assert op['esc']['cft_scan_rate'] == 0.0 and op['esc']['meets_target']
    assert op['esc']['cttr_second_half'] == 1.0 and op['fixed:4']['cttr_run'] == [1.0, 1.0, 0.0, 0.0]
    p = op['fixed:4']['paired_first_minus']
    assert p['difference'] == pytest.approx(0.5) and p['runs'] == 4 and p['ci95'] > 0
    # A looser target admits the lowest T: every scan of run 0 (1 run in 4) holds two false tracks.
    loose = operating_point(study, runs, cft_target=0.3)
    assert loose['esc']['t_c'] == T_GRID[0]
    assert loose['esc']['cft_scan_rate'] == pytest.approx(0.25) and loose['esc']['cft_per_scan'] == pytest.approx(0.5)


def test_unmet_target_is_flagged_at_the_strictest_t_c():
    study = StudyConfig(scans=4, methods=parse_methods('esc,fixed:2'))
    runs = synthetic_runs(2, 4, {'esc': 2.0, 'fixed:2': 0.6}, {'esc': {0}, 'fixed:2': {0}})
    op = operating_point(study, runs)
    assert not op['esc']['meets_target'] and op['esc']['t_c'] == T_GRID[-1]
    assert op['fixed:2']['meets_target']


def test_the_sweep_keeps_confirmation_once_existence_has_exceeded_t():
    sweep = ConfirmationSweep()
    has, nf = sweep.update([7, 8], [0.97, 0.7], np.array([1, -1]))
    assert has[T_GRID < 0.97].all() and not has[T_GRID >= 0.97].any()
    assert (nf[T_GRID < 0.7] == 1).all() and (nf[T_GRID >= 0.7] == 0).all()
    has, _ = sweep.update([7], [0.2], np.array([1]))  # existence fell: still confirmed where it was
    assert has[T_GRID < 0.97].all()

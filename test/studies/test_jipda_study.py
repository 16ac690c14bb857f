"""The JIPDA study: simulation geometry and the trackers' mismatched models, the per-run scores,
the T_c sweep, the calibration's choice, determinism."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from sonar_tracking.core.records import TRACK_DTYPE
from sonar_tracking.studies import jipda_table
from sonar_tracking.studies.jipda_study import (
    CELLS,
    CONDITIONS,
    GOSPA,
    JipdaStudy,
    _score,
    _tracker,
    for_condition,
    run_once,
    simulate,
)


@pytest.mark.parametrize('geometry', ['crossing', 'parallel'])
def test_simulated_geometry(geometry):
    study = JipdaStudy(geometry=geometry, scans=41)
    truth, scans, param = simulate(study, np.random.default_rng(4))
    assert truth.shape == (41, 2, 4) and len(scans) == 41
    speeds = np.hypot(truth[..., 2], truth[..., 3])
    np.testing.assert_allclose(speeds, study.speed)
    gap = np.hypot(*(truth[:, 0, :2] - truth[:, 1, :2]).T)
    if geometry == 'crossing':
        assert 5.0 <= param <= 20.0 and gap[20] == pytest.approx(0.0, abs=1e-9)
        heading = np.degrees(np.arctan2(truth[0, :, 3], truth[0, :, 2]))
        assert abs((heading[0] - heading[1] + 180) % 360 - 180) == pytest.approx(param)
    else:
        assert 2.0 <= param <= 4.0
        np.testing.assert_allclose(gap, param * study.cell)
    assert study.cell == pytest.approx(math.sqrt(12 * 5.0 * 2500 * math.radians(0.1)))
    win = study.window
    assert win.area == pytest.approx(600.0 * 600.0, rel=1e-9)
    for z, R, rho in scans:
        assert z.shape[1] == 2 and R.shape == (len(z), 2, 2) and np.all(np.linalg.eigvalsh(R) > 0)
        np.testing.assert_array_equal(rho, study.clutter_density)


@pytest.mark.parametrize('geometry', ['crossing', 'parallel'])
def test_manoeuvring_targets_turn_and_still_meet_at_the_middle_scan(geometry):
    study = for_condition('manoeuvre', geometry, scans=41)
    truth, _, param = simulate(study, np.random.default_rng(8))
    heading = np.unwrap(np.arctan2(truth[:, :, 3], truth[:, :, 2]), axis=0)
    rate = np.degrees(np.diff(heading, axis=0))                                   # deg per scan (1 s)
    np.testing.assert_allclose(rate, np.broadcast_to(rate[0], rate.shape), atol=1e-9)   # a constant turn
    assert np.all((np.abs(rate[0]) >= 1.0) & (np.abs(rate[0]) <= 3.0))
    gap = np.hypot(*(truth[:, 0, :2] - truth[:, 1, :2]).T)
    if geometry == 'crossing':
        assert gap[20] == pytest.approx(0.0, abs=1e-9)
        np.testing.assert_allclose(np.hypot(truth[..., 2], truth[..., 3]), study.speed)
    else:                                              # a formation turn: the same rate, the gap kept
        assert rate[0, 0] == pytest.approx(rate[0, 1])
        np.testing.assert_allclose(gap, param * study.cell)


def test_unresolved_targets_give_one_detection_between_them():
    study = for_condition('unresolved', 'crossing', scans=21, p_detect=1.0, clutter_density=1e-12)
    truth, scans, _ = simulate(study, np.random.default_rng(1))
    gap = np.hypot(*(truth[:, 0, :2] - truth[:, 1, :2]).T)
    counts = np.array([len(z) for z, _, _ in scans])
    assert counts[10] == 1 and np.all(counts[gap > 2 * study.cell] == 2)
    for k in np.flatnonzero(gap < 0.5 * study.cell):
        z = scans[k][0][0]
        assert np.hypot(*(z - truth[k, :, :2].mean(axis=0))) < 0.5 * study.cell + 30.0


def test_scmde_gives_the_trackers_estimated_densities():
    study = for_condition('scmde', 'crossing', scans=30)
    _, scans, _ = simulate(study, np.random.default_rng(2))
    rho = np.concatenate([r for _, _, r in scans])
    assert rho.std() > 0 and 0.5 < np.median(rho) / study.clutter_density < 2.0
    assert _tracker(study, 'ipda').config.clutter.source == 'detection'
    assert _tracker(JipdaStudy(), 'ipda').config.clutter.source == 'constant'


def test_wrong_detection_probability_is_given_to_the_trackers():
    high, low = for_condition('pd_high', 'crossing'), for_condition('pd_low', 'parallel')
    assert (high.p_detect, _tracker(high, 'jipda').config.detection.probability) == (0.8, 0.9)
    assert (low.p_detect, _tracker(low, 'ipda').config.detection.probability) == (0.9, 0.8)
    assert ('parallel', 'unresolved') not in CELLS and len(CELLS) == 2 * len(CONDITIONS) - 1


def tracks(*rows):
    out = np.zeros(len(rows), TRACK_DTYPE)
    for i, (tid, x, y) in enumerate(rows):
        out[i]['track_id'], out[i]['x'], out[i]['y'], out[i]['confirmed'] = tid, x, y, 1
    return out


def test_scores_count_a_swap_and_coalescence():
    study = JipdaStudy(scans=4)
    truth = np.zeros((4, 2, 4))
    truth[:, 0, :2], truth[:, 1, :2] = (0.0, 0.0), (0.0, 50.0)
    outputs = [tracks((1, 0, 0), (2, 0, 50)), tracks((1, 0, 50), (2, 0, 0)),     # swap: both targets
               tracks((1, 0, 48), (2, 0, 45)),                                   # two tracks on target 1
               tracks((3, 0, 1))]                                                # a new track, no swap
    s = _score(study, truth, outputs, np.eye(4))
    assert s['swaps'] == 2.0 and s['coalescence'] == pytest.approx(1 / 4)
    assert s['gospa'] > 0 and 0 <= s['cttr'] <= 1 and GOSPA.c == 20.0


def test_run_is_a_function_of_its_seed_and_records_the_t_c_of_its_trackers():
    study = JipdaStudy(geometry='parallel', scans=15, confirm_by_method=(('ipda', 0.9), ('jipda', 0.995)))
    seeds = np.random.SeedSequence(3).spawn(2)
    a, b = run_once(study, seeds[0]), run_once(study, seeds[0])
    assert a == b and a != run_once(study, seeds[1])
    assert a['ipda']['confirm'] == 0.9 and a['jipda']['confirm'] == 0.995


def test_the_sweep_at_its_lowest_t_c_is_the_run_itself():
    """The trackers confirm at the sweep grid's lowest T_c, so the swept GOSPA there is the run's; higher
    T_c confirm fewer tracks."""
    study = JipdaStudy(geometry='crossing', scans=30, sweep_grid=(0.5, 0.9, 0.999))
    r = run_once(study, np.random.SeedSequence(5).spawn(1)[0])
    for m in ('ipda', 'jipda'):
        assert r[m]['confirm'] == 0.5 and len(r[m]['swept_gospa']) == 3
        assert r[m]['swept_gospa'][0] == pytest.approx(r[m]['gospa'])


def test_calibration_chooses_the_least_gospa_inside_the_run_near_the_screen(monkeypatch):
    """The sweep screens (least swept GOSPA at 0.9 for IPDA, 0.999 for JIPDA); the screened value and its
    neighbours run inside the run and the least GOSPA there wins, with the paper range marked."""
    grid = (0.5, 0.9, 0.99, 0.999)
    swept = {'ipda': [5.0, 3.0, 4.0, 6.0], 'jipda': [5.0, 4.0, 3.5, 3.0]}
    inside = {'ipda': {0.5: 9.0, 0.9: 4.0, 0.99: 3.5}, 'jipda': {0.99: 2.5, 0.999: 2.9}}

    def fake_runs(study, seeds, runs, pool, label, progress):
        if study.sweep_grid:
            return [{m: {'swept_gospa': swept[m]} for m in swept}]
        own = dict(study.confirm_by_method)
        return [{m: {'gospa': inside[m][t]} for m, t in own.items()}]

    monkeypatch.setattr(jipda_table, '_runs', fake_runs)
    cal = jipda_table.calibrate(JipdaStudy(), (3,), 2, grid=grid)
    assert cal['ipda']['screened']['value'] == 0.9 and cal['jipda']['screened']['value'] == 0.999
    assert cal['ipda']['t_c'] == 0.99 and cal['ipda']['in_paper_range'] is True
    assert cal['jipda']['t_c'] == 0.99 and cal['jipda']['in_run'] == {'0.99': 2.5, '0.999': 2.9}
    monkeypatch.setitem(inside['jipda'], 0.999, 2.0)
    cal = jipda_table.calibrate(JipdaStudy(), (3,), 2, grid=grid)
    assert cal['jipda']['t_c'] == 0.999 and cal['jipda']['in_paper_range'] is False
    assert cal['jipda']['grid_edge'] == 'highest' and cal['ipda']['grid_edge'] is None
    assert cal['jipda']['reason'] == ('least calibration GOSPA inside the run: 2.000 m at T_c 0.999 against 2.500 m '
                                      'at 0.99')


def test_conditions_are_known():
    with pytest.raises(ValueError, match='condition'):
        for_condition('magic', 'crossing')
    with pytest.raises(ValueError):
        replace(JipdaStudy(), clutter_model='guess')

"""The ESC paper study machinery: methods, Monte Carlo determinism, summaries, Algorithm 1."""
from __future__ import annotations

import numpy as np
import pytest

from sonar_tracking.studies import algorithm1
from sonar_tracking.studies.esc_study import (
    Method,
    StudyConfig,
    design_pd,
    fixed_pd,
    parse_methods,
    resolution_cell_area,
    run_once,
    summarise,
)
from sonar_tracking.studies.montecarlo import run_monte_carlo, run_seeds


def test_methods_parse():
    assert parse_methods('esc, fixed:2,esc:5') == (Method('esc', None, True), Method('fixed:2', 2.0, False),
                                                   Method('esc:5', 5.0, True))
    for bad, match in (('esc,esc', 'repeat'), ('fixed', 'unknown method'), ('fixed:x', 'must be a number'),
                       ('fixed:-1', 'must be > 0'), ('kalman', 'unknown method'), ('', 'no methods')):
        with pytest.raises(ValueError, match=match):
            parse_methods(bad)


def test_algorithm1_relations():
    assert resolution_cell_area(5.0, 5.0) == pytest.approx(300.0)      # the paper's V_rc
    snr = 10 ** 0.8
    pd = design_pd(8.0, 2.21e-5, 300.0)
    assert pd ** (1 + snr) == pytest.approx(2.21e-5 * 300.0)           # line 3, P_fa = P_D^(1+SNR)
    assert fixed_pd(2.0, 8.0) == pytest.approx(0.76, abs=0.01)         # lam = 1, eq. 16 for the target
    cfg = algorithm1.Algorithm1Config(snr_db=8.0, pd_step=0.01)
    cands = algorithm1.candidates(cfg)
    assert cands and all(cfg.rho_min < rho < cfg.rho_max for _, rho in cands)
    for pd, rho in cands:
        assert rho * cfg.v_rc == pytest.approx(pd ** (1 + snr))
    assert [pd for pd, _ in cands] == sorted([pd for pd, _ in cands], reverse=True)


def test_choose_takes_the_smallest_t_c_meeting_the_rate_and_the_peak():
    cfg = algorithm1.Algorithm1Config()
    t = len(algorithm1.T_GRID)
    results = {}
    peaks = [2, 4, 6, 9, 6, 4, 2]
    for i, peak in enumerate(peaks):
        nf = np.zeros((10, t), int)
        nf[0, :20] = 1                         # below T_GRID[20] the CFT rate is 0.1
        has = np.zeros((10, t), bool)
        has[:peak] = True
        results[(0.7 - 0.02 * i, 10.0 ** (-4 - 0.2 * i))] = [{'has_ctt': has, 'n_false': nf}]
    out = algorithm1.choose(cfg, results)
    assert all(c['t_c'] == pytest.approx(algorithm1.T_GRID[20]) for c in out['candidates'])
    assert out['desired_clutter_density'] == out['raw_argmax_density'] == pytest.approx(10.0 ** -4.6)
    assert out['t_c'] == pytest.approx(algorithm1.T_GRID[20]) and out['pd'] == pytest.approx(0.64)


def test_choose_smooths_a_noisy_plateau():
    cfg = algorithm1.Algorithm1Config()
    t = len(algorithm1.T_GRID)
    # A rise to a plateau with one lucky spike at the low end: the smoothed peak sits on the plateau.
    counts = [40, 50, 62, 66, 67, 64, 60, 80, 58]
    results = {}
    for i, c in enumerate(counts):
        has = np.zeros((100, t), bool)
        has[:c] = True
        results[(0.5, 10.0 ** (-3 - 0.25 * i))] = [{'has_ctt': has, 'n_false': np.zeros((100, t), int)}]
    out = algorithm1.choose(cfg, results)
    assert out['raw_argmax_density'] == pytest.approx(10.0 ** (-3 - 0.25 * 7))
    assert 10.0 ** (-3 - 0.25 * 6) <= out['desired_clutter_density'] <= 10.0 ** (-3 - 0.25 * 2)


def test_a_candidate_run_has_scan_by_threshold_counts():
    cfg = algorithm1.Algorithm1Config(scans=6, models='cv')
    r = algorithm1.run_candidate((cfg, 0.8, 2e-5), run_seeds(1, 1)[0])
    assert r['has_ctt'].shape == r['n_false'].shape == (6, len(algorithm1.T_GRID))
    # Raising T_c never adds confirmed tracks.
    assert (np.diff(r['n_false'].astype(int), axis=1) <= 0).all()
    assert (np.diff(r['has_ctt'].astype(int), axis=1) <= 0).all()


def test_monte_carlo_results_do_not_depend_on_the_number_of_processes():
    study = StudyConfig(scans=8, methods=parse_methods('esc,fixed:4'))
    one = run_monte_carlo(run_once, study, 3, seed=5, jobs=1)
    two = run_monte_carlo(run_once, study, 3, seed=5, jobs=2)
    for a, b in zip(one, two):
        for m in a:
            for k in a[m]:
                assert np.array_equal(a[m][k], b[m][k], equal_nan=True), (m, k)
    s = summarise(study, one)
    assert set(s) == {'esc', 'fixed:4'}
    for v in s.values():
        assert len(v['cttr']) == len(v['rmse']) == len(v['threshold']) == len(v['clutter_density']) == 8
        assert v['cft_rate'] >= 0.0 and all(0.0 <= c <= 1.0 for c in v['cttr'])
    assert s['fixed:4']['threshold'] == [4.0] * 8 and s['esc']['threshold'][0] == 3.0


def test_fixed_threshold_2_collapses_in_heavy_clutter():
    """Figure 9: at lam 0.8 a threshold of 2 buries the target in clutter (P_fa 0.2 per cell)."""
    study = StudyConfig(lam=0.8, scans=30, methods=parse_methods('esc,fixed:2'), confirm=0.995)
    runs = run_monte_carlo(run_once, study, 6, seed=11, jobs=2)
    s = summarise(study, runs)
    assert np.mean(s['fixed:2']['cttr'][15:]) < 0.5 * np.mean(s['esc']['cttr'][15:])
    assert np.mean(s['fixed:2']['clutter_density']) > 20 * np.mean(s['esc']['clutter_density'][15:])
    assert s['esc']['threshold'][-1] == pytest.approx(6.4, rel=0.08)

"""The shared rules of the comparative studies: seed sets, operating points, read-back, corrected
paired intervals with a rank interval, agreement of seed sets, GOSPA settings."""
from __future__ import annotations

import argparse
import math
from itertools import product

import numpy as np
import pytest
from scipy.stats import t as student_t

from sonar_tracking.studies.evidence import (
    Correction,
    GospaSpec,
    SeedError,
    SeedSplit,
    _signed_rank_cdf,
    add_seed_arguments,
    agreement,
    choose_minimum,
    choose_smallest_meeting,
    choose_smallest_within_one_se,
    compare,
    format_comparisons,
    grid_edge,
    paired_interval,
    paper_range,
    parse_seeds,
    per_run_values,
    rank_interval,
    read_back,
    seed_split_from_args,
)


def test_seeds_parse_lists_and_ranges_and_refuse_the_rest():
    assert parse_seeds('21, 22') == (21, 22) and parse_seeds('3-5,9') == (3, 4, 5, 9)
    for bad, why in [('', 'no seeds'), ('4,x', 'whole number'), ('5-3', 'backwards'), ('1,1', 'repeat'),
                     ('-2', '>= 0')]:
        with pytest.raises(SeedError, match=why):
            parse_seeds(bad)


@pytest.mark.parametrize('calibration, evaluation, tuned, why', [
    ((1,), (1, 2), (), 'overlap: \\[1\\]'),
    ((1, 2), (3,), (), 'at least 2 evaluation seeds'),
    ((), (2, 3), (), 'calibration seed'),
    ((1,), (2, 2), (), 'repeat'),
    ((1,), (2, 7), (7, 77), 'tuned on'),
])
def test_seed_split_refuses_sets_that_are_not_out_of_sample(calibration, evaluation, tuned, why):
    with pytest.raises(SeedError, match=why):
        SeedSplit(calibration, evaluation, tuned)


def test_seed_arguments_of_a_command():
    p = argparse.ArgumentParser()
    add_seed_arguments(p, calibration='11', evaluation='21,22', runs=50)
    args = p.parse_args([])
    split = seed_split_from_args(args)
    assert split.calibration == (11,) and split.evaluation == (21, 22) and args.calibration_runs == 50
    args = p.parse_args(['--calibration-seeds', '5-6', '--seeds', '6,7'])
    with pytest.raises(SeedError, match='overlap: \\[6\\]'):
        seed_split_from_args(args)
    with pytest.raises(SeedError, match='--runs'):
        seed_split_from_args(p.parse_args(['--runs', '1']))


def test_operating_point_rules():
    grid = [0.5, 0.9, 0.99, 0.999]
    c = choose_smallest_meeting(grid, [0.1, 0.004, 0.01, 0.0], 0.005)      # not monotone: the first that meets
    assert c == {'index': 1, 'value': 0.9, 'rate': 0.004, 'meets_target': True}
    c = choose_smallest_meeting(grid, [0.1, 0.1, 0.1, 0.1], 0.005)
    assert c['index'] == 3 and not c['meets_target']
    assert choose_minimum([1, 2, 3], [2.0, float('nan'), 1.0]) == {'index': 2, 'value': 3.0, 'cost': 1.0}
    assert choose_minimum([1, 2, 3], [1.0, 1.0, 2.0])['value'] == 1.0   # a tie: the smallest value
    with pytest.raises(ValueError):
        choose_minimum([1, 2], [float('nan')] * 2)
    assert [grid_edge(i, grid) for i in range(4)] == ['lowest', None, None, 'highest']


def test_the_one_standard_error_rule_takes_the_smallest_value_within_the_best_values_noise():
    rng = np.random.default_rng(7)
    noise = rng.normal(0.0, 0.02, 20)                      # standard error of each mean: about 0.0045
    grid = [1.0, 2.0, 3.0]
    # 2 and 3 differ by far less than their noise; 1 lies 0.05 below
    samples = [0.92 + noise, 0.970 + noise[::-1], 0.971 + noise]
    c = choose_smallest_within_one_se(grid, samples)
    assert c['value'] == 2.0 and c['allowed_any']
    assert c['bar'] == pytest.approx(0.971 + noise.mean() - noise.std(ddof=1) / np.sqrt(20))
    assert c['means'][2] == pytest.approx(0.971 + noise.mean()) and len(c['ses']) == 3
    # a value not allowed never wins nor sets the bar
    assert choose_smallest_within_one_se(grid, samples, [True, False, True])['value'] == 3.0
    # a clear winner is not overruled by a smaller value outside its noise
    assert choose_smallest_within_one_se(grid, [0.5 + noise, 0.6 + noise, 0.9 + noise])['value'] == 3.0
    none = choose_smallest_within_one_se(grid, samples, [False] * 3)
    assert none['value'] == 1.0 and not none['allowed_any']
    with pytest.raises(ValueError):
        choose_smallest_within_one_se(grid, samples[:2])


def test_paper_range_marks_a_value_outside_with_its_reason():
    assert paper_range(0.98, None, 0.99, 'why') == {'paper_range': [None, 0.99], 'in_paper_range': True,
                                                     'reason': None}
    out = paper_range(0.9996, None, 0.99, 'no T_c <= 0.99 meets the target')
    assert out['in_paper_range'] is False and out['reason'] == 'no T_c <= 0.99 meets the target'
    assert paper_range(3, None, None)['in_paper_range'] is None


def test_read_back_compares_every_run_with_the_chosen_value():
    assert read_back(0.999, [0.999, 0.999]) == {'chosen': 0.999, 'read_back': [0.999], 'runs': 2, 'equal': True}
    r = read_back(0.999, [0.999, 0.5])
    assert r['read_back'] == [0.5, 0.999] and not r['equal']
    assert not read_back(2, [])['equal']


def test_correction_is_bonferroni_over_the_tables_intervals():
    c = Correction(16)
    assert c.level == pytest.approx(1 - 0.05 / 16) and c.describe()['method'] == 'bonferroni'
    assert '16 paired intervals' in c.text()
    with pytest.raises(ValueError):
        Correction(0)


def test_paired_t_interval_at_the_corrected_level():
    rng = np.random.default_rng(3)
    a, b = rng.normal(1.0, 1.0, 40), rng.normal(0.0, 1.0, 40)
    level = Correction(8).level
    iv = paired_interval(a, b, level)
    d = a - b
    half = student_t.ppf(0.5 + level / 2, 39) * d.std(ddof=1) / math.sqrt(40)
    assert iv['difference'] == pytest.approx(d.mean()) and iv['half'] == pytest.approx(half)
    assert iv['low'] == pytest.approx(d.mean() - half) and iv['runs'] == 40 and iv['level'] == level
    # Runs where either value is not finite are left out of both.
    a[0] = np.nan
    assert paired_interval(a, b, level)['runs'] == 39
    assert paired_interval([1.0], [0.0])['half'] is None


def test_signed_rank_null_distribution_is_exact():
    n = 7
    sums = [sum(r for r, s in zip(range(1, n + 1), signs) if s) for signs in product((0, 1), repeat=n)]
    want = np.cumsum(np.bincount(sums, minlength=n * (n + 1) // 2 + 1)) / 2 ** n
    np.testing.assert_allclose(_signed_rank_cdf(n), want)
    # Published two-sided 5 % critical values: n = 10 -> 8, n = 30 -> 137 (k = T + 1).
    for n, crit in ((10, 8), (30, 137)):
        assert int(np.searchsorted(_signed_rank_cdf(n), 0.025, side='right')) == crit + 1


def test_rank_interval_is_not_moved_by_a_few_extreme_runs():
    """Heavy tails: one run carried far off moves the mean and widens the t interval across zero; the
    Hodges-Lehmann interval of the same differences stays below zero."""
    rng = np.random.default_rng(5)
    d = rng.normal(-0.05, 0.03, 60)
    d[0] = 8.0
    iv = paired_interval(d, np.zeros_like(d), 0.95)
    assert iv['low'] < 0 < iv['high']
    assert iv['rank_high'] < 0 and iv['rank_estimate'] == pytest.approx(-0.05, abs=0.02)
    # The normal approximation (n > 60) and the exact one meet at the boundary.
    big = rank_interval(rng.normal(0.0, 1.0, 200), 0.95)
    assert big['low'] < 0 < big['high']
    assert rank_interval([0.1, 0.2], 0.999)['low'] is None     # too few runs for the level


def test_agreement_of_two_seed_sets():
    rng = np.random.default_rng(7)
    same = [paired_interval(rng.normal(0.1, 0.05, 100), np.zeros(100), 0.99) for _ in range(2)]
    ok = agreement(same[0], same[1], 0.99)
    assert ok['agree'] and ok['overlap'] and abs(ok['delta']) <= ok['half']
    shifted = paired_interval(rng.normal(0.4, 0.05, 100), np.zeros(100), 0.99)
    bad = agreement(same[0], shifted, 0.99)
    assert not bad['agree'] and not bad['overlap'] and bad['delta'] == pytest.approx(-0.3, abs=0.03)
    assert agreement(paired_interval([1.0], [0.0]), same[0], 0.99)['agree'] is None


def test_compare_per_seed_pooled_and_agreement():
    rng = np.random.default_rng(9)
    samples = {str(s): {'a': rng.normal(1.0, 0.2, 30), 'b': rng.normal(0.8, 0.2, 30)} for s in (21, 22)}
    corr = Correction(4)
    c = compare(samples, 'a', 'b', corr, heavy_tailed=True)
    assert set(c['seeds']) == {'21', '22'} and c['pooled']['runs'] == 60 and c['agree'] is True
    pooled = np.concatenate([samples[s]['a'] - samples[s]['b'] for s in ('21', '22')])
    assert c['pooled']['difference'] == pytest.approx(pooled.mean()) and c['pooled']['level'] == corr.level
    assert list(c['agreement']) == ['21|22']
    rows = format_comparisons([('Scenario 2', 'a − b, CTTR', c)], ['21', '22'])
    assert rows[0] == '| group | comparison | pooled: mean ± t [HL: rank interval] | seed 21 | seed 22 | agree |'
    assert rows[2].startswith('| Scenario 2 | a − b, CTTR | +0.') and '[HL +0.' in rows[2] and rows[2].endswith(
        '| yes |')


def test_gospa_settings_are_stated_and_used():
    g = GospaSpec(c=20.0)
    assert g.describe() == {'c': 20.0, 'p': 2.0, 'alpha': 2.0} and g.text() == 'GOSPA (c = 20 m, p = 2, alpha = 2)'
    r = g(np.array([[0.0, 0.0], [100.0, 0.0]]), np.array([[3.0, 4.0]]))
    assert r.distance == pytest.approx(math.sqrt(25.0 + 20.0 ** 2 / 2)) and r.missed == 1 and r.false == 0


def test_per_run_values_round_for_json():
    assert per_run_values([1.23456789, float('nan'), 2.0]) == [1.23457, None, 2.0]

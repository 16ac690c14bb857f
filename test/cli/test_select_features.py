"""``sonar_eval select-features``: arguments, a small real run end to end, the JSON and the plot."""
from __future__ import annotations

import argparse
import json

import pytest

from sonar_tracking.cli import select_features as sf


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='select-features')
    sf.add_arguments(parser)
    return parser.parse_args(list(argv))


@pytest.mark.parametrize('method', ['sfs', 'sbs'])
def test_small_run_writes_the_error_curve_and_subsets(tmp_path, method, capsys):
    out, png = tmp_path / 'sel.json', tmp_path / 'sel.png'
    args = parse('--method', method, '--runs', '2', '--situations', '1-4,7', '--sweeps', '4', '--json', str(out),
                 '--plot', str(png))
    assert sf.main_args(args) == 0
    r = json.loads(out.read_text())
    s = r['summary']
    assert r['method'] == method and r['runs'] == 2 and r['situations'] == [1, 2, 3, 4, 7]
    assert len(s['mean_test_error']) == len(s['std_test_error']) == 30
    assert all(0.0 <= e <= 1.0 for e in s['mean_test_error'])
    assert len(s['consensus_top5']) == 5 and s['paper_features'] == [20, 17, 3, 6, 24]
    assert sum(s['top5_counts'].values()) == 5 * 2
    assert set(s['class_counts']) <= {'clutter', 'pontoon', 'cube', 'prism', 'reflector', 'sphere'}
    for run in r['per_run']:
        assert [len(x) for x in run['subsets']] == list(range(1, 31))
        assert sorted(run['order']) == list(range(1, 31))
        assert run['best_subset'] == run['subsets'][run['best_k'] - 1]
        assert run['regions']['train'] > 0 and run['regions']['test'] > 0
    assert png.stat().st_size > 10_000
    assert 'paper [20, 17, 3, 6, 24]' in capsys.readouterr().out


def test_same_seed_same_result(tmp_path):
    results = []
    for name in ('a.json', 'b.json'):
        assert sf.main_args(parse('--runs', '1', '--situations', '2,4', '--sweeps', '4', '--json',
                                  str(tmp_path / name))) == 0
        r = json.loads((tmp_path / name).read_text())
        r.pop('wall_s')
        results.append(r)
    assert results[0] == results[1]


def test_too_little_data_is_an_error_that_says_so(tmp_path, capsys):
    assert sf.main_args(parse('--situations', '2', '--sweeps', '2', '--json', str(tmp_path / 'x.json'))) == 1
    assert 'too few labelled regions' in capsys.readouterr().err


@pytest.mark.parametrize('argv, message', [
    (['--runs', '0'], '--runs must be >= 1'),
    (['--sigma', '-1'], '--sigma must be a positive number'),
    (['--situations', '0-3'], 'outside 1-14'),
    (['--sweeps', '-2'], '--sweeps must be >= 0'),
])
def test_bad_arguments_are_refused(tmp_path, argv, message, capsys):
    assert sf.main_args(parse('--json', str(tmp_path / 'x.json'), *argv)) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / 'x.json').exists()

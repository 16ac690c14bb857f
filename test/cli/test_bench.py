"""The benchmark harness: table, JSON, ratios against baselines (structure, never timing limits)."""
from __future__ import annotations

import json

from sonar_tracking.cli import bench
from sonar_tracking.cli.sonar_eval import main


def test_run_case_reports_ordered_statistics():
    calls = []
    r = bench.run_case(bench.Case(name='t', group='g', make=lambda: (lambda: calls.append(1)), repeats=7))
    assert r.repeats == 7 and r.number >= 1
    assert 0 < r.min_s <= r.p25_s <= r.median_s <= r.p75_s <= r.max_s
    assert len(calls) == 1 + (7 + 1) * r.number or len(calls) > 7 * r.number  # warm-up + calibration + repeats


def test_bench_cli_writes_json_with_ratio(tmp_path, capsys):
    out = tmp_path / 'bench.json'
    assert main(['bench', 'adapters.cloud_to_array', '--repeats', '3', '--json', str(out)]) == 0
    table = capsys.readouterr().out
    assert 'adapters.cloud_to_array' in table and 'vs adapters.cloud_to_array.loop' in table
    data = json.loads(out.read_text())
    assert set(data) == {'machine', 'cases'}
    by_name = {c['name']: c for c in data['cases']}
    case, base = by_name['adapters.cloud_to_array'], by_name['adapters.cloud_to_array.loop']
    assert case['compare_to'] == base['name']
    assert case['ratio'] == base['median_s'] / case['median_s']
    assert case['limit_s'] == 1e-3 and case['meets_limit'] == (case['median_s'] <= 1e-3)


def test_bench_list_and_unknown_pattern(capsys):
    assert main(['bench', '--list']) == 0
    listed = capsys.readouterr().out
    for name in ('adapters.image_to_array', 'adapters.array_to_image', 'adapters.cloud_to_array',
                 'adapters.array_to_cloud'):
        assert name in listed
    assert main(['bench', 'no-such-case']) == 2


def test_a_baselines_own_baseline_comes_along(monkeypatch):
    """Asking for a case whose baseline has a baseline of its own runs all three (it raised KeyError)."""
    quick = {name: bench.Case(name=name, group='g', make=lambda: (lambda: None), repeats=3, compare_to=base)
             for name, base in (('a', 'b'), ('b', 'c'), ('c', None))}
    monkeypatch.setattr(bench, 'cases', lambda: dict(quick))
    results = {r.name: r for r in bench.run(['a'])}
    assert set(results) == {'a', 'b', 'c'}
    assert results['a'].ratio == results['b'].median_s / results['a'].median_s
    assert results['b'].ratio == results['c'].median_s / results['b'].median_s

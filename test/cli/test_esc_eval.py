"""sonar_eval scenario1 / scenario2 / desired-density: JSON, plots and the desired-density table."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from sonar_tracking.cli.sonar_eval import main
from sonar_tracking.core.detection import DesiredDensityTable


@pytest.mark.parametrize('scenario, methods', [('scenario1', 'esc,fixed:2'), ('scenario2', 'esc,fixed:3')])
def test_scenario_json_and_plot(tmp_path, scenario, methods, capsys):
    out, png = tmp_path / 'r.json', tmp_path / 'r.png'
    assert main([scenario, '--runs', '2', '--scans', '6', '--seed', '3', '--methods', methods, '--jobs', '1',
                 '--json', str(out), '--plot', str(png)]) == 0
    data = json.loads(out.read_text())
    assert {'runs', 'scans', 'desired_clutter_density', 'wall_s', 'methods'} <= set(data)
    assert data['runs'] == 2 and data['scans'] == 6 and set(data['methods']) == set(methods.split(','))
    for m in data['methods'].values():
        assert {'cttr', 'rmse', 'threshold', 'clutter_density', 'cft_rate'} <= set(m)
        assert len(m['cttr']) == len(m['threshold']) == 6
    assert png.stat().st_size > 10_000
    assert 'CTTR 2nd half' in capsys.readouterr().out


def test_bad_methods_exit_2(capsys):
    assert main(['scenario1', '--methods', 'esc,magic']) == 2
    assert 'unknown method' in capsys.readouterr().err


def test_desired_density_table_is_usable_by_the_detector(tmp_path):
    table, js = tmp_path / 'dd.yaml', tmp_path / 'dd.json'
    assert main(['desired-density', '--snr-db', '6', '10', '--runs', '2', '--scans', '6', '--pd-step', '0.1',
                 '--models', 'cv', '--jobs', '1', '--table', str(table), '--json', str(js)]) == 0
    text = table.read_text()
    assert text.startswith('# Desired clutter density') and 'sonar_eval desired-density' in text
    t = DesiredDensityTable.load(table)
    assert list(t.snr_db) == [6.0, 10.0]
    mid = t.lookup(8.0)
    assert min(t.density) <= mid <= max(t.density)
    assert np.log(mid) == pytest.approx(np.mean(np.log(t.density)))
    details = json.loads(js.read_text())['snr']
    assert [d['snr_db'] for d in details] == [6.0, 10.0] and all(d['candidates'] for d in details)
    assert yaml.safe_load(text)['models'] == 'cv'


ESC_TABLE = ['esc-table', '--runs', '2', '--calibration-runs', '3', '--scans', '8', '--max-steps', '1',
             '--calibration-seeds', '2', '--seeds', '4,5', '--jobs', '1']


def test_esc_table_runs_every_tracker_at_its_chosen_t_c_and_keeps_its_figures_consistent(tmp_path, capsys):
    """Acceptance: the JSON records, per method, the T_c read back from each evaluation run's tracker,
    and it is the T_c chosen on the calibration seeds; the table's figures are those of the runs."""
    out = tmp_path / 'table.json'
    assert main([*ESC_TABLE, '--json', str(out)]) == 0
    text = capsys.readouterr().out
    r = json.loads(out.read_text())
    assert r['seeds'] == {'calibration': [2], 'evaluation': [4, 5], 'tuned_on': [1, 7, 77]}
    assert [s['name'] for s in r['studies']] == ['Scenario 1, lambda 1.2', 'Scenario 1, lambda 0.8', 'Scenario 2']
    assert r['gospa'] == {'c': 20.0, 'p': 2.0, 'alpha': 2.0} and r['correction']['intervals'] == 16
    assert text.count('| Scenario 1, lambda 1.2 | ') == 4 + 6 and text.count('| Scenario 2 | ') == 3 + 4
    for s in r['studies']:
        for m in s['methods'].values():
            rb, cal = m['t_c_read_back'], m['calibration']
            assert rb['read_back'] == [cal['t_c']] and rb['equal'] and rb['runs'] == 4
            assert cal['t_c'] == cal['path'][-1]['t_c'] or cal['meets_target']
            assert any(p['t_c'] == cal['t_c'] for p in cal['path'])
            for seed in ('4', '5'):
                ev = m['evaluation'][seed]
                assert len(ev['per_run']['cttr']) == 2
                assert ev['cttr'] == pytest.approx(np.mean(ev['per_run']['cttr']), abs=1e-5)
        first = s['methods']['esc']['evaluation']
        for c in s['comparisons']:
            other = s['methods'][c['second']]['evaluation']
            for seed in ('4', '5'):
                want = np.mean(np.subtract(first[seed]['per_run'][c['metric']], other[seed]['per_run'][c['metric']]))
                assert c['seeds'][seed]['difference'] == pytest.approx(want, abs=1e-4)
            assert c['pooled']['runs'] == 4 and c['pooled']['level'] == pytest.approx(1 - 0.05 / 16)


@pytest.mark.parametrize('argv, message', [
    (['--calibration-seeds', '4', '--seeds', '4,5'], 'overlap: [4]'),
    (['--seeds', '201'], 'at least 2 evaluation seeds'),
    (['--seeds', '1,202'], 'tuned on'),
    (['--runs', '1'], '--runs'),
])
def test_esc_table_refuses_seed_sets_that_are_not_out_of_sample(argv, message, capsys):
    assert main(['esc-table', *argv]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize('argv', [['--help'], ['esc-table', '--help'], ['select-features', '--help']])
def test_help_texts_format(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 0 and '--cluster' in capsys.readouterr().out

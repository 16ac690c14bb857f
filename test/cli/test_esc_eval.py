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


def test_esc_table_reduced_prints_the_table_and_keeps_its_figures_consistent(tmp_path, capsys):
    out = tmp_path / 'table.json'
    assert main(['esc-table', '--runs', '3', '--scans', '8', '--seed', '2', '--jobs', '1', '--json', str(out)]) == 0
    text = capsys.readouterr().out
    r = json.loads(out.read_text())
    assert [s['name'] for s in r['studies']] == ['Scenario 1, lambda 1.2', 'Scenario 1, lambda 0.8', 'Scenario 2']
    assert text.count('| Scenario 1, lambda 1.2 |') == 4 and text.count('| Scenario 2 |') == 3
    for s in r['studies']:
        esc = s['methods']['esc']
        for name, m in s['methods'].items():
            assert len(m['cttr_run']) == 3
            assert m['cft_scan_rate'] <= m['cft_per_scan'] + 1e-12   # a CFT scan holds one or more CFTs
            if m['meets_target']:
                assert m['cft_scan_rate'] <= 0.005
            if name != 'esc':
                want = np.mean(np.subtract(esc['cttr_run'], m['cttr_run']))
                assert m['paired_first_minus']['difference'] == pytest.approx(want)


def test_esc_table_refuses_bad_arguments(capsys):
    assert main(['esc-table', '--runs', '1']) == 2
    assert '--runs >= 2' in capsys.readouterr().err


@pytest.mark.parametrize('argv', [['--help'], ['esc-table', '--help'], ['select-features', '--help']])
def test_help_texts_format(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 0 and '--cluster' in capsys.readouterr().out

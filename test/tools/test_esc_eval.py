"""sonar_eval scenario1 / scenario2 / desired-density: JSON, plots and the desired-density table."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from sonar_tracking.core.detection import DesiredDensityTable
from sonar_tracking.tools.sonar_eval import main


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

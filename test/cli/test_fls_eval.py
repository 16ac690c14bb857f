"""sonar_eval fls: JSON shape of the issue, the plot, the sea-trial settings and clear errors."""
from __future__ import annotations

import json

import pytest

from sonar_tracking.cli.fls_eval import SEA_TRIAL, study_for
from sonar_tracking.cli.sonar_eval import main


def test_situation_json_and_plot(tmp_path, capsys):
    out, png = tmp_path / 'fls.json', tmp_path / 'fls.png'
    assert main(['fls', '--situation', '8', '--runs', '2', '--seed', '3', '--methods', 'af,mf,ekf', '--jobs', '1',
                 '--json', str(out), '--plot', str(png)]) == 0
    data = json.loads(out.read_text())
    assert {'methods', 'wall_s'} <= set(data) and data['wall_s'] > 0
    assert list(data['methods']) == ['af', 'mf', 'ekf']
    n_frames = len(data['stamps'])
    assert data['situation'] == 8 and data['runs'] == 2 and len(data['target_ids']) == 2
    for m in data['methods'].values():
        assert len(m['cle_mean']) == len(m['lost_frames']) == len(m['cle']) == 2
        assert all(len(row) == n_frames for row in m['cle'])
        assert all(v is None or v >= 0 for row in m['cle'] for v in row)
        assert all(0 <= lf <= n_frames for lf in m['lost_frames'])
        assert 'identity_kept_rate' in m                  # situation 8 crosses
        assert len(m['cle_run']) == 2
    for name in ('mf', 'ekf'):
        p = data['methods'][name]['paired_with_first']
        assert p['first'] == 'af' and p['runs'] <= 2
    printed = capsys.readouterr().out
    assert png.stat().st_size > 10_000
    assert 'identity kept' in printed and 'af - method' in printed


def test_sea_trial_preset_settings():
    study = study_for(None, SEA_TRIAL, ('af',))
    assert study.scenario == 'sea_trial' and study.config.particles == 200
    assert study_for(None, SEA_TRIAL, ('af',), particles=150).config.particles == 150
    assert study_for(3, None, ('af',)).config.particles == 300


@pytest.mark.parametrize('args, message', [
    (['--situation', '8', '--methods', 'af,magic'], 'unknown method'),
    (['--situation', '8', '--runs', '0'], '--runs and --jobs'),
    (['--situation', '8', '--particles', '3'], '--particles'),
])
def test_bad_arguments_exit_2_with_a_message(tmp_path, capsys, args, message):
    assert main(['fls', *args, '--json', str(tmp_path / 'x.json')]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / 'x.json').exists()


@pytest.mark.parametrize('args', [['--situation', '15'], ['--situation', '3', '--preset', SEA_TRIAL], []])
def test_argument_errors_from_the_parser(tmp_path, capsys, args):
    with pytest.raises(SystemExit) as exc:
        main(['fls', *args, '--json', str(tmp_path / 'x.json')])
    assert exc.value.code == 2
    assert 'error' in capsys.readouterr().err


def test_fls_table_reduced_prints_the_table_and_agrees_with_sonar_eval_fls(tmp_path, capsys):
    """The docs/results table's command, reduced: every figure is the one `sonar_eval fls` gives for the
    same situation, runs and seed, and the corrections add up (the EKF corrects only by regions)."""
    table, single = tmp_path / 'table.json', tmp_path / 'fls.json'
    assert main(['fls-table', '--runs', '3', '--seed', '5', '--situations', '8', '--methods', 'af,af18,ekf',
                 '--jobs', '1', '--json', str(table)]) == 0
    printed = capsys.readouterr().out
    assert '| situation | af CLE | af18 CLE | ekf CLE | af − af18 | af − ekf |' in printed
    assert '\n| 8 | ' in printed
    assert main(['fls', '--situation', '8', '--runs', '3', '--seed', '5', '--methods', 'af,af18,ekf', '--jobs', '1',
                 '--json', str(single)]) == 0
    rows = json.loads(table.read_text())['situations'][0]['methods']
    ref = json.loads(single.read_text())['methods']
    for m in ('af', 'af18', 'ekf'):
        runs = [v for v in ref[m]['cle_run'] if v is not None]
        assert rows[m]['cle'] == pytest.approx(sum(runs) / len(runs), rel=1e-12)
        assert rows[m]['identity_kept_rate'] == ref[m]['identity_kept_rate']
        c = rows[m]['corrections']
        assert c == ref[m]['corrections'] and c['image'] + c['region'] > 0 and c['coasting'] >= 0
    assert rows['af18']['paired_first_minus'] == ref['af18']['paired_with_first']
    assert rows['ekf']['corrections']['image'] == 0 and rows['ekf']['corrections']['image_share'] == 0.0
    assert 0.0 < rows['af']['corrections']['image_share'] < 1.0


def test_fls_table_refuses_bad_arguments(capsys):
    assert main(['fls-table', '--runs', '1']) == 2
    assert main(['fls-table', '--runs', '3', '--situations', '15']) == 2
    assert main(['fls-table', '--runs', '3', '--methods', 'af,xx']) == 2
    assert 'error' in capsys.readouterr().err

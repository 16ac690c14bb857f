"""sonar_eval fls: JSON shape of the issue, the plot, the sea-trial settings and clear errors."""
from __future__ import annotations

import json

import numpy as np
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


FLS_TABLE = ['fls-table', '--runs', '2', '--calibration-runs', '2', '--situations', '8', '--methods', 'af,wf,ekf',
             '--hits', '1,3', '--calibration-seeds', '3', '--seeds', '5,6', '--jobs', '1']


def test_fls_table_ranks_on_capped_cle_at_each_methods_own_confirmation(tmp_path, capsys):
    """The docs/results table's command, reduced: confirm_hits per method chosen on the calibration seed
    (least GOSPA) and read back from every evaluation run's tracker; methods ranked on the capped CLE,
    the other figures beside it, every figure the mean of its runs."""
    out = tmp_path / 'table.json'
    assert main([*FLS_TABLE, '--json', str(out)]) == 0
    printed = capsys.readouterr().out
    assert ('| situation | rank | method | confirm_hits (read back) | capped CLE [m] | lost frames / target | '
            'track breaks / target | GOSPA [m] | CLE of tracked frames [m] | identity kept | image share |') in printed
    r = json.loads(out.read_text())
    assert r['gospa'] == {'c': 1.5, 'p': 2.0, 'alpha': 2.0} and r['correction']['intervals'] == 8
    s = r['situations'][0]
    capped = {m: s['methods'][m]['pooled']['cle_capped'] for m in ('af', 'wf', 'ekf')}
    assert s['ranking'] == sorted(capped, key=capped.get)
    for row in s['methods'].values():
        cal = row['calibration']
        assert cal['confirm_hits'] == [1, 3][int(np.argmin(cal['gospa_by_value']))]
        rb = row['confirm_hits_read_back']
        assert rb['read_back'] == [cal['confirm_hits']] and rb['equal'] and rb['runs'] == 4
        runs = row['per_run']['5']['cle_capped'] + row['per_run']['6']['cle_capped']
        assert row['pooled']['cle_capped'] == pytest.approx(np.mean(runs), abs=1e-5)
        assert all(0.0 <= v <= s['gate'] for v in runs)
        assert row['pooled']['lost'] >= 0 and row['pooled']['breaks'] >= 0
        c = row['corrections']
        assert c['image'] + c['region'] > 0 and c['coasting'] >= 0
    assert s['methods']['ekf']['corrections']['image'] == 0
    assert [(c['second'], c['metric']) for c in s['comparisons']] == [
        (m, k) for m in ('wf', 'ekf') for k in ('cle_capped', 'lost', 'breaks', 'gospa')]
    assert all(c['heavy_tailed'] and set(c['seeds']) == {'5', '6'} for c in s['comparisons'])


@pytest.mark.parametrize('argv', [['--runs', '1'], ['--runs', '3', '--situations', '15'],
                                  ['--runs', '3', '--methods', 'af,xx'], ['--hits', '0,2'],
                                  ['--calibration-seeds', '5201', '--seeds', '5201,5202'],
                                  ['--seeds', '4000,5202']])
def test_fls_table_refuses_bad_arguments(argv, capsys):
    assert main(['fls-table', *argv]) == 2
    assert 'error' in capsys.readouterr().err

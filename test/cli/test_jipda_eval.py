"""sonar_eval jipda: the reduced study prints the tables, writes its JSON with each tracker's T_c read
back, and refuses seed sets that are not out of sample."""
from __future__ import annotations

import json

import numpy as np
import pytest

from sonar_tracking.cli.sonar_eval import main


def test_jipda_reduced_json_shape_and_read_back(tmp_path, capsys):
    out = tmp_path / 'a.json'
    assert main(['jipda', '--runs', '3', '--calibration-runs', '2', '--scans', '12', '--calibration-seeds', '3',
                 '--seeds', '5,6', '--conditions', 'matched,unresolved', '--jobs', '1', '--json', str(out)]) == 0
    text = capsys.readouterr().out
    assert '| crossing | unresolved |' in text and '| parallel | matched |' in text and 'jipda:' in text
    assert '| parallel | unresolved |' not in text          # parallel targets are never unresolved
    r = json.loads(out.read_text())
    assert r['seeds']['evaluation'] == [5, 6] and r['gospa'] == {'c': 20.0, 'p': 2.0, 'alpha': 2.0}
    assert [(c['geometry'], c['condition']) for c in r['cells']] == [
        ('crossing', 'matched'), ('crossing', 'unresolved'), ('parallel', 'matched')]
    assert r['correction']['intervals'] == 3 * 6
    for c in r['cells']:
        assert c['study']['scans'] == 12 and c['study']['unresolved'] == (c['condition'] == 'unresolved')
        for m in ('ipda', 'jipda'):
            rb = c['methods'][m]['t_c_read_back']
            assert rb['read_back'] == [c['methods'][m]['calibration']['t_c']] and rb['equal'] and rb['runs'] == 6
            assert c['study']['confirm_by_method'] == [['ipda', c['methods']['ipda']['calibration']['t_c']],
                                                       ['jipda', c['methods']['jipda']['calibration']['t_c']]]
        gos = c['comparisons'][0]
        assert gos['metric'] == 'gospa' and gos['heavy_tailed'] and gos['pooled']['runs'] == 6
        d = np.subtract(c['per_run']['5']['jipda']['gospa'], c['per_run']['5']['ipda']['gospa'])
        assert gos['seeds']['5']['difference'] == pytest.approx(d.mean(), abs=1e-4)
        assert c['gospa_lead_holds'] == (gos['pooled']['high'] < 0 and gos['agree'])


@pytest.mark.parametrize('argv, message', [
    (['--runs', '1'], '--runs'),
    (['--calibration-seeds', '401', '--seeds', '401,402'], 'overlap: [401]'),
    (['--seeds', '1,402'], 'tuned on'),
    (['--conditions', 'matched,magic'], 'unknown or repeated'),
    (['--geometry', 'parallel', '--conditions', 'unresolved'], 'no cell left'),
])
def test_jipda_refuses_bad_arguments(argv, message, capsys):
    assert main(['jipda', *argv]) == 2
    assert message in capsys.readouterr().err

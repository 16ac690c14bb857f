"""sonar_eval jipda: the reduced study prints the table, writes its JSON, and repeats for a seed."""
from __future__ import annotations

import json

from sonar_tracking.cli.sonar_eval import main


def _run(tmp_path, name, capsys):
    out = tmp_path / name
    assert main(['jipda', '--runs', '3', '--scans', '10', '--seed', '5', '--jobs', '1', '--json', str(out)]) == 0
    return json.loads(out.read_text()), capsys.readouterr().out


def test_jipda_reduced_json_shape_and_determinism(tmp_path, capsys):
    a, text = _run(tmp_path, 'a.json', capsys)
    assert '| crossing | gospa |' in text and '| parallel | cttr |' in text and 'jipda:' in text
    assert a['runs'] == 3 and a['seed'] == 5 and [g['geometry'] for g in a['geometries']] == ['crossing', 'parallel']
    for g in a['geometries']:
        assert set(g['means']) == {'ipda', 'jipda'} and len(g['per_run']) == 3
        assert set(g['jipda_minus_ipda']) == {'gospa', 'missed', 'false', 'swaps', 'coalescence', 'cttr'}
        assert g['study']['scans'] == 10
        gos = g['jipda_minus_ipda']['gospa']
        assert gos['runs'] == 3 and gos['ci95'] is not None
    b, _ = _run(tmp_path, 'b.json', capsys)
    a.pop('wall_s'), b.pop('wall_s')
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def test_jipda_refuses_bad_arguments(capsys):
    assert main(['jipda', '--runs', '1']) == 2
    assert 'need --runs >= 2' in capsys.readouterr().err

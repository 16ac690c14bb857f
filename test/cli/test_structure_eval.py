"""sonar_eval structure, reduced: the harbour scene without targets, with and without rejection."""
import json

from sonar_tracking.cli.sonar_eval import main


def test_structure_command_counts_tracks_on_structure_with_and_without_rejection(tmp_path, capsys):
    out = tmp_path / 's.json'
    status = main(['structure', '--scenarios', 'structure_only:harbour', '--frames', '12', '--seed', '1',
                   '--json', str(out)])
    rows = {r['rejection']: r for r in json.loads(out.read_text())['rows']}
    assert set(rows) == {'on', 'off'} and rows['on']['frames'] == rows['off']['frames'] == 12
    assert rows['off']['on_structure'] > 0, 'without rejection the piles, quay and band make tracks'
    assert rows['on']['on_structure'] == 0 and status == 0
    assert 'structure_only:harbour' in capsys.readouterr().out

"""Golden outputs: every ``sonar_eval`` study command, run reduced and seeded, gives the stored numbers.

The references in ``golden/`` were recorded before the package was reorganised into one folder per
role; a refactoring must leave them identical. A change meant to alter results updates them with
``SONAR_GOLDEN_UPDATE=1`` and says why in its commit. Wall times (keys ``wall_s``) and the comment
lines of YAML tables (which carry the date) are not compared; everything else is, exactly.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

GOLDEN = Path(__file__).resolve().parent / 'golden'
CONFIG = Path(__file__).resolve().parents[2] / 'config'
SONAR_EVAL = 'sonar_tracking.cli.sonar_eval'
MANIFEST = json.loads((GOLDEN / 'manifest.json').read_text())
UPDATE = os.environ.get('SONAR_GOLDEN_UPDATE') == '1'


def without_wall_time(data: Any) -> Any:
    """``data`` with every ``wall_s`` key removed, at any depth."""
    if isinstance(data, dict):
        return {k: without_wall_time(v) for k, v in data.items() if k != 'wall_s'}
    if isinstance(data, list):
        return [without_wall_time(v) for v in data]
    return data


def comparable(path: Path) -> Any:
    """What of an output file is compared: JSON without wall times, YAML without comments, CSV as is."""
    text = path.read_text()
    if path.suffix == '.json':
        return without_wall_time(json.loads(text))
    if path.suffix == '.yaml':
        return [line for line in text.splitlines() if not line.lstrip().startswith('#')]
    return text.splitlines()


def test_comparison_ignores_wall_time_only():
    a = {'wall_s': 1.0, 'rows': [{'wall_s': 2.0, 'cttr': 0.5}]}
    b = {'wall_s': 9.0, 'rows': [{'wall_s': 3.0, 'cttr': 0.5}]}
    assert without_wall_time(a) == without_wall_time(b)
    b['rows'][0]['cttr'] = 0.5000000000000001
    assert without_wall_time(a) != without_wall_time(b)


@pytest.mark.parametrize('case', sorted(MANIFEST['cases']))
def test_study_output_is_the_stored_reference(case, tmp_path):
    spec = MANIFEST['cases'][case]
    argv = [a.format(golden=GOLDEN, config=CONFIG) for a in spec['argv']]
    proc = subprocess.run([sys.executable, '-m', SONAR_EVAL, *argv], cwd=tmp_path, capture_output=True,
                          text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for name in spec['outputs']:
        produced = tmp_path / name
        assert produced.is_file(), f'{case} wrote no {name}: {proc.stdout}'
        if UPDATE:
            shutil.copyfile(produced, GOLDEN / name)
        assert comparable(produced) == comparable(GOLDEN / name), f'{case}: {name} differs from the reference'

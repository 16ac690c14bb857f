"""docs/parameters.md is generated from the nodes' declared parameters and is current."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from sonar_tracking.cli import parameters_doc

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.ros


def check(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.parameters_doc', '--check', '--output', str(path)],
                          cwd=ROOT, capture_output=True, text=True, timeout=240)


def test_every_node_is_in_the_reference():
    modules = {p.stem for p in (ROOT / 'sonar_tracking' / 'nodes').glob('*.py') if p.stem != '__init__'}
    assert set(parameters_doc.NODES) == modules


def test_the_reference_is_current_and_a_stale_one_is_refused(tmp_path):
    """The shipped file is what the nodes declare today; a file with one default changed is not."""
    current = check(ROOT / 'docs' / 'parameters.md')
    assert current.returncode == 0, current.stdout + current.stderr
    stale = tmp_path / 'parameters.md'
    text = (ROOT / 'docs' / 'parameters.md').read_text()
    assert '| `threshold.initial` | double | 3 |' in text
    stale.write_text(text.replace('| `threshold.initial` | double | 3 |', '| `threshold.initial` | double | 4 |'))
    refused = check(stale)
    assert refused.returncode == 1 and 'not current' in refused.stderr

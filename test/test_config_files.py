"""Every parameter file in config/ names real parameters with valid values."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from sonar_tracking.nodes.seaking_sim import SimNodeConfig

CONFIG = Path(__file__).resolve().parents[1] / 'config'
NODES = {'seaking_sim': SimNodeConfig}


@pytest.mark.parametrize('path', sorted(CONFIG.glob('*.yaml')), ids=lambda p: p.name)
def test_parameter_file_is_valid(path):
    data = yaml.safe_load(path.read_text())
    assert isinstance(data, dict) and data, f'{path.name} is empty'
    for node, section in data.items():
        params = dict(section['ros__parameters'])
        cls = NODES[node]
        known = {s.name for s in cls.settings()}
        assert not set(params) - known, f'unknown parameters {sorted(set(params) - known)}'
        config = cls.for_scenario(params.pop('scenario'), params.pop('preset', ''), **params)
        assert config.flat()['seed'] == params.get('seed', 0)

"""Every parameter file in config/ names real parameters of its node, with valid values."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from sonar_tracking.io import param_files
from sonar_tracking.nodes.active_detector import DetectorNodeConfig
from sonar_tracking.nodes.fls_features import FlsNodeConfig
from sonar_tracking.nodes.gpf_tracker import GpfNodeConfig
from sonar_tracking.nodes.imm_ipda_tracker import TrackerNodeConfig
from sonar_tracking.nodes.seaking_sim import SimNodeConfig

CONFIG = Path(__file__).resolve().parents[1] / 'config'


def sim_config(params):
    return SimNodeConfig.for_scenario(params.pop('scenario'), params.pop('preset', ''), **params)


#: node name -> (config class, how to build it from a params section)
NODES = {
    'seaking_sim': (SimNodeConfig, sim_config),
    'active_detector': (DetectorNodeConfig, DetectorNodeConfig.from_flat),
    'imm_ipda_tracker': (TrackerNodeConfig, TrackerNodeConfig.from_flat),
    'fls_features': (FlsNodeConfig, FlsNodeConfig.from_flat),
    'gpf_tracker': (GpfNodeConfig, GpfNodeConfig.from_flat),
}


def parameter_files():
    """ROS parameter files: every YAML in config/ but tables and stack files."""
    return sorted(p for p in CONFIG.glob('*.yaml')
                  if p.name != 'desired_density.yaml' and not p.name.startswith('stack_'))


@pytest.mark.parametrize('path', parameter_files(), ids=lambda p: p.name)
def test_parameter_file_is_valid(path):
    data = yaml.safe_load(path.read_text())
    assert isinstance(data, dict) and data, f'{path.name} is empty'
    for key in data:
        node = key.removeprefix('/**/')
        assert key == f'/**/{node}', f'{path.name}: section {key!r} applies in one namespace only; key it /**/{node}'
        assert node in NODES, f'{path.name}: unknown node {node}'
        cls, build = NODES[node]
        params = param_files.parameters_for(data, node, '/auv1')
        known = {s.name for s in cls.settings()}
        assert not set(params) - known, f'unknown parameters {sorted(set(params) - known)}'
        flat = build(dict(params)).flat()
        for name, value in params.items():
            assert flat[name] == (tuple(value) if isinstance(value, list) else value), name


@pytest.mark.parametrize('path', sorted(CONFIG.glob('stack_*.yaml')), ids=lambda p: p.name)
def test_stack_file_is_valid(path):
    from sonar_tracking.cli.sonar_stack import load_stack
    stack = load_stack(path)
    assert stack.nodes and all(n.params_file is None or n.params_file.exists() for n in stack.nodes)

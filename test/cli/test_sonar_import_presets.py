"""Sensor presets (config/sensors/*.yaml): every name is a real setting with a valid value.

The node sections are checked against the nodes' config dataclasses (Config.settings()), the
``sonar_import`` section against ImportOptions, and every value must carry a reason comment.
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from sonar_tracking.cli.sonar_import import load_preset
from sonar_tracking.io import param_files
from sonar_tracking.io.importers import ImportOptions
from sonar_tracking.nodes.active_detector import DetectorNodeConfig
from sonar_tracking.nodes.fls_features import FlsNodeConfig
from sonar_tracking.nodes.gpf_tracker import GpfNodeConfig
from sonar_tracking.nodes.imm_ipda_tracker import TrackerNodeConfig

SENSORS = Path(__file__).resolve().parents[2] / 'config' / 'sensors'
NODES = {'active_detector': DetectorNodeConfig, 'fls_features': FlsNodeConfig, 'gpf_tracker': GpfNodeConfig,
         'imm_ipda_tracker': TrackerNodeConfig}
PRESETS = sorted(SENSORS.glob('*.yaml'))


def test_the_sensor_families_have_presets():
    assert {p.stem for p in PRESETS} == {'micron_seaking', 'ping360', 'oculus_m750d', 'gemini_720', 'aris_didson'}


@pytest.mark.parametrize('path', PRESETS, ids=lambda p: p.stem)
def test_preset_names_real_settings(path):
    data = yaml.safe_load(path.read_text())
    nodes = {key.removeprefix('/**/') for key in data}
    assert set(data) == {f'/**/{node}' for node in nodes}, 'every section must apply under any namespace'
    assert nodes - {'sonar_import'} <= set(NODES), f'unknown node sections {nodes - set(NODES)}'
    options = ImportOptions.from_flat(load_preset(str(path)))
    assert options.flat()  # constructing validated every importer value
    for node in sorted(nodes - {'sonar_import'}):
        cls = NODES[node]
        params = param_files.parameters_for(data, node, '/auv1')
        known = {s.name for s in cls.settings()}
        assert not set(params) - known, f'{node}: unknown parameters {sorted(set(params) - known)}'
        flat = cls.from_flat(params).flat()
        for name, value in params.items():
            assert flat[name] == (tuple(value) if isinstance(value, list) else value), name


@pytest.mark.parametrize('path', PRESETS, ids=lambda p: p.stem)
def test_every_preset_value_has_a_reason(path):
    for line in path.read_text().splitlines():
        body = line.split('#', 1)[0]
        if ':' in body and body.split(':', 1)[1].strip():
            assert '#' in line and line.split('#', 1)[1].strip(), f'{path.name}: no reason for {line.strip()!r}'


def test_a_wrong_name_fails(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('sonar_import:\n  ros__parameters:\n    head_clockwize: true  # typo\n')
    with pytest.raises(Exception, match='head_clockwize'):
        ImportOptions.from_flat(load_preset(str(bad)))

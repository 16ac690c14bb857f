"""The warm-ups take every compiled path: after them a real run of the component compiles no kernel
for a new argument type (each check in a fresh interpreter, where numba knows no signature yet)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

_SIGNATURES = '''
import sys
import numba
import numpy as np


def signatures():
    """Every compiled kernel of the package with the argument types it has code for."""
    out = {}
    for name, mod in list(sys.modules.items()):
        if name.startswith('sonar_tracking.core'):
            for attr, value in vars(mod).items():
                if isinstance(value, numba.core.registry.CPUDispatcher):
                    out[f'{value.py_func.__module__}.{value.py_func.__name__}'] = set(map(str, value.signatures))
    return out


def check(before):
    after = signatures()
    new = {k: sorted(v - before.get(k, set())) for k, v in after.items() if v - before.get(k, set())}
    assert not new, f'compiled after the warm-up: {new}'
    print('kernels', len(after), 'signatures', sum(map(len, after.values())))
'''

_HARBOUR = _SIGNATURES + '''
from sonar_tracking.io import param_files
from sonar_tracking.ros import warmup
from sonar_tracking.core.detection import ActiveDetector, best_track_focus
from sonar_tracking.studies.esc_study import StudyConfig, run_once
from sonar_tracking.sim import SimConfig, Simulator
from sonar_tracking.core.tracking import ImmIpdaTracker
from sonar_tracking.core.tracking.coverage import Coverage
from sonar_tracking.core.tracking.detections import detections_to_measurements
from sonar_tracking.nodes.active_detector import DetectorNodeConfig, desired_density, detector_config
from sonar_tracking.nodes.imm_ipda_tracker import TrackerNodeConfig
from sonar_tracking.resources import config_path


def params(name, node):
    return param_files.parameters_for(param_files.load(config_path(name)), node)


trk_cfg = TrackerNodeConfig.from_flat(params('imm_ipda.yaml', 'imm_ipda_tracker'))
det_flat = {**params('active_detector.yaml', 'active_detector'), 'esc.density_source': 'best_track',
            'esc.desired_clutter_density': 7.52e-5}
det_cfg = DetectorNodeConfig.from_flat(det_flat)
warmup.tracker(trk_cfg)
warmup.detector(detector_config(det_cfg), desired_density(det_cfg))
before = signatures()

# The harbour stack: Scenario 2 through the detector and the tracker as the nodes drive them.
sim = Simulator(SimConfig.for_scenario('scenario2', duration=40.0), np.random.default_rng(1))
det = ActiveDetector(detector_config(det_cfg), desired_density(det_cfg))
trk = ImmIpdaTracker(trk_cfg)
focus = None
for k in range(40):
    s = sim.next_sector()
    r = det.process(s.amplitudes, s.geometry, s.pose, focus, stamp=s.stamp)
    z, R, rho, _ = detections_to_measurements(r.detections)
    window = Coverage(s.pose[0], s.pose[1], s.pose[2], s.geometry.range_min, s.geometry.range_max,
                      s.geometry.angle_min, s.geometry.angle_max)
    focus = best_track_focus(trk.step(s.stamp, z, R, rho, coverage=window))
# Scenario 1 at the fixed threshold 2: hundreds of detections and tentative tracks a scan.
run_once(StudyConfig(scans=12, methods=StudyConfig().methods), np.random.SeedSequence(3))
check(before)
'''

_GPF = _SIGNATURES + '''
from sonar_tracking.ros import warmup
from sonar_tracking.core.gpf import GpfTracker
from sonar_tracking.nodes.gpf_tracker import GpfNodeConfig
from sonar_tracking.cli.bench_cases import gpf as cases

cfg = GpfNodeConfig()
warmup.gpf(lambda: GpfTracker(cfg, np.random.default_rng(0), feature_config=cfg.features))
before = signatures()
for scene in (cases.TANK, cases.SQUARE):
    grid, frames = cases._frames(15, scene)
    trk = GpfTracker(cfg, np.random.default_rng(5), feature_config=cfg.features)
    for stamp, img, reg in frames[:6]:
        trk.step(stamp, img, grid, reg, (0.0, 0.0, 0.0))
    assert sum(t.confirmed for t in trk.tracks) >= 10
check(before)
'''


@pytest.mark.parametrize('script', [_HARBOUR, _GPF], ids=['harbour', 'gpf'])
def test_after_the_warm_up_a_real_run_compiles_nothing(script):
    r = subprocess.run([sys.executable, '-c', textwrap.dedent(script)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    assert 'kernels' in r.stdout


def test_the_tracker_warm_up_keeps_settings_its_shortcut_would_break():
    """The warm-up lowers T_c to confirm within its scans; where that breaks a rule (T_c above the
    termination threshold), it runs with the settings as they are."""
    from sonar_tracking.core.tracking import TrackerConfig
    from sonar_tracking.ros import warmup
    cfg = TrackerConfig.from_flat({'existence.terminate': 0.6, 'existence.initial': 0.7, 'existence.confirm': 0.9})
    assert warmup.tracker(cfg) > 0.0


@pytest.mark.ros
def test_a_failing_warm_up_is_logged_and_the_node_starts(inproc, monkeypatch):
    from sonar_tracking.nodes.imm_ipda_tracker import ImmIpdaTrackerNode
    from sonar_tracking.ros import warmup
    from sonar_tracking.ros.node import SonarNode
    said = []

    def boom(config):
        raise RuntimeError('no compiler here')

    original = SonarNode.get_logger
    monkeypatch.setattr(warmup, 'tracker', boom)

    class Logger:
        def __init__(self, inner):
            self.inner = inner

        def warning(self, text, *a, **k):
            said.append(text)
            return self.inner.warning(text, *a, **k)

        def __getattr__(self, name):
            return getattr(self.inner, name)

    monkeypatch.setattr(SonarNode, 'get_logger', lambda self: Logger(original(self)))
    node = inproc(ImmIpdaTrackerNode)
    assert node.tracker is not None
    assert any('kernel warm-up failed (RuntimeError: no compiler here)' in s for s in said)

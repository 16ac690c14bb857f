"""Sensor presets and scenarios.

Sensors: ``harbour`` (ESC paper §2, §5), ``seaking675`` and ``seaking325`` (FLS paper Table 1).

Scenarios:

* ``scenario1``: ESC §5.1. Harbour sonar at (-2000, 0) m; one target from (50, 200) m at
  12 m/s. The paper does not give the course (its Figure 3 is not in the text): we use 45 deg.
  SNR 8 dB, clutter lam 1.2 (set 0.8 for §5.1.2), 50 scans.
* ``scenario2``: ESC §5.2. Same sonar and start; Table 2: CV for 20 s, CCW 3 deg/s for 30 s, CW
  3 deg/s for 30 s, CV for 20 s, starting on course 0 deg. Figure 15's two regions: lam 1.6
  everywhere except lam 0.8 beyond the line the target crosses at scan 50 (the end of its CCW
  turn, where it heads +y): the half-plane ``y > y(50)``. 100 scans.
* ``fls1`` .. ``fls14``: FLS paper Table 5 in a tank: static SeaKing at the origin looking +x,
  sector +/-45 deg, 30 m range; targets 1 pontoon, 2 cube, 3 triangular prism, 4 reflector,
  5 sphere, towed by ropes (random deviation, wobbling heading). "Same direction": side by side
  toward the sonar; "opposite direction, crossed": X-shaped paths crossing at mid-time.
* ``sea_trial``: FLS §5.2: AUV at 0.5 m/s, two targets at 0.6-0.7 m/s with current disturbance,
  crossing at mid-time, 50 m range.
* ``clutter``: no targets (for measuring false-alarm statistics), any sensor.
* ``<name>_structured`` for ``scenario1``, ``scenario2`` and ``fls1`` .. ``fls14``: the same targets
  (same seed, same paths) in a scene with static structure (tank walls or harbour quay,
  breakwater and piles), a seabed band, transducer ringdown, and 8-bit dB output
  (:data:`STRUCTURE_PRESETS`; see :mod:`.structure`).
* ``structure_only``: the structured tank (SeaKing) or harbour with no target at all.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sonar_tracking.sim.motion import DraggedTrajectory, ScriptedTrajectory, Segment, StaticTrajectory
from sonar_tracking.sim.scene import ClutterRegion, Scene, Target
from sonar_tracking.sim.shapes import shape
from sonar_tracking.sim.structure import HARBOUR_SONAR_XY

__all__ = ['SENSOR_PRESETS', 'STRUCTURE_PRESETS', 'SCENARIOS', 'ScenarioInfo', 'scenario_info', 'build_scene',
           'FLS_TARGETS', 'HARBOUR_SONAR_XY']

#: Flat setting overrides of each sensor preset (names as in SimConfig).
SENSOR_PRESETS: dict[str, dict] = {
    'harbour': {},
    'seaking675': {'seaking.frequency_khz': 675.0, 'seaking.beam_width_deg': 1.5,
                   'seaking.vertical_beam_width_deg': 40.0, 'seaking.absorption_db_per_m': 0.2},
    'seaking325': {'seaking.frequency_khz': 325.0, 'seaking.beam_width_deg': 3.0,
                   'seaking.vertical_beam_width_deg': 20.0, 'seaking.absorption_db_per_m': 0.09},
}

#: Flat setting overrides of the structured scenarios, by layout (applied after the scenario's own).
STRUCTURE_PRESETS: dict[str, dict] = {
    'tank': {'structure.kind': 'tank', 'output.coding': 'db'},
    'harbour': {'structure.kind': 'harbour', 'structure.seabed_range_min': 1900.0,
                'structure.seabed_range_max': 2000.0, 'structure.texture_scale': 60.0,
                'structure.ringdown_length': 10.0, 'output.coding': 'db'},
}

#: FLS paper §3.4 target numbering.
FLS_TARGETS = {1: 'pontoon', 2: 'cube', 3: 'prism', 4: 'reflector', 5: 'sphere'}


@dataclass(frozen=True)
class ScenarioInfo:
    """What a scenario needs and its defaults."""

    name: str
    sensors: tuple[str, ...]          # compatible sensor presets, first = default
    duration: float                   # s
    clutter_lambda: float
    snr_db: float
    overrides: tuple[tuple[str, object], ...] = ()  # flat SimConfig overrides (sensor window etc.)
    description: str = ''
    structured: bool = False          # STRUCTURE_PRESETS apply (by sensor)


_SEAKING = ('seaking675', 'seaking325')
_TANK = (('seaking.range_max', 30.0), ('seaking.scan_min_deg', -45.0), ('seaking.scan_max_deg', 45.0))

_FLS_TEXT = {
    1: 'Only first target moves.', 2: 'Only second target moves.', 3: 'Only third target moves.',
    4: 'Only fourth target moves.', 5: 'First and fourth targets move together in the same direction.',
    6: 'Second and fourth targets move together in the same direction.',
    7: 'Fourth and fifth targets move together in the same direction.',
    8: 'Third and fourth targets move in opposite directions; their trajectories cross.',
    9: 'Third and fifth targets move in opposite directions; their trajectories cross.',
    10: 'First and second targets move in opposite directions; their trajectories cross.',
    11: 'Second and third targets move in opposite directions; their trajectories cross.',
    12: 'Second, third and fourth targets move together in the same direction.',
    13: 'Second, third and fourth targets move together in opposite directions.',
    14: 'Second target does not move.',
}

SCENARIOS: dict[str, ScenarioInfo] = {
    'scenario1': ScenarioInfo('scenario1', ('harbour',), 50.0, 1.2, 8.0,
                              description='ESC paper Scenario 1: one CV target, homogeneous clutter'),
    'scenario2': ScenarioInfo('scenario2', ('harbour',), 100.0, 1.6, 8.0,
                              description='ESC paper Scenario 2: manoeuvring target, clutter regions lam 1.6 / 0.8'),
    'clutter': ScenarioInfo('clutter', ('harbour',) + _SEAKING, 0.0, 1.0, 0.0, description='clutter only'),
    'sea_trial': ScenarioInfo('sea_trial', _SEAKING, 160.0, 1.0, 20.0,
                              (('seaking.range_max', 50.0), ('seaking.scan_min_deg', -60.0),
                               ('seaking.scan_max_deg', 60.0)),
                              description='FLS paper sea trial: AUV at 0.5 m/s, two crossing towed targets'),
}
for _n, _text in _FLS_TEXT.items():
    SCENARIOS[f'fls{_n}'] = ScenarioInfo(f'fls{_n}', _SEAKING, 80.0 if _n <= 7 or _n == 12 else 60.0, 1.0, 20.0,
                                         _TANK, description=f'FLS paper Table 5, situation {_n}: {_text}')

for _base in [n for n in SCENARIOS if n.startswith(('scenario', 'fls'))]:
    _i = SCENARIOS[_base]
    SCENARIOS[f'{_base}_structured'] = dataclasses.replace(
        _i, name=f'{_base}_structured', structured=True,
        description=f'{_i.description}; with walls, seabed band, ringdown and 8-bit dB output')
SCENARIOS['structure_only'] = ScenarioInfo('structure_only', _SEAKING + ('harbour',), 60.0, 1.0, 0.0, _TANK,
                                           'static structure, seabed band and ringdown, no target, 8-bit dB '
                                           'output (tank on SeaKing, harbour on the harbour sonar)', True)


def scenario_info(name: str) -> ScenarioInfo:
    """The scenario's info; ValueError lists the known names."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f'unknown scenario {name!r}; known: {sorted(SCENARIOS)}') from None


def build_scene(name: str, rng: np.random.Generator, clutter_lambda: float, snr_db: float, duration: float,
                sensor: str) -> Scene:
    """Build the named scenario's scene; ``rng`` fixes the random parts (towed-target deviations)."""
    info = scenario_info(name)
    if sensor not in info.sensors:
        raise ValueError(f'scenario {name} runs on {"/".join(info.sensors)}, not {sensor}')
    base = name.removesuffix('_structured')
    builder: Callable[..., Scene] = _BUILDERS.get(base) or _fls
    scene = builder(base, rng, snr_db)
    scene.lam = clutter_lambda
    scene.duration = duration if duration > 0 else math.inf
    if name in ('clutter', 'structure_only') and sensor == 'harbour':
        scene.platform = StaticTrajectory(*HARBOUR_SONAR_XY)
    return scene


def _harbour_platform() -> StaticTrajectory:
    return StaticTrajectory(*HARBOUR_SONAR_XY)


def _scenario1(name: str, rng: np.random.Generator, snr_db: float) -> Scene:
    v = 12.0 / math.sqrt(2.0)
    return Scene([Target(1, ScriptedTrajectory(50.0, 200.0, v, v), snr_db=snr_db)], _harbour_platform())


SCENARIO2_SEGMENTS = (Segment(20.0), Segment(30.0, math.radians(3.0)), Segment(30.0, -math.radians(3.0)),
                      Segment(20.0))


def _scenario2(name: str, rng: np.random.Generator, snr_db: float) -> Scene:
    traj = ScriptedTrajectory(50.0, 200.0, 12.0, 0.0, SCENARIO2_SEGMENTS)
    y50 = float(traj.state(50.0)[1])
    yellow = ClutterRegion(0.8, np.array([[-1e5, y50], [1e5, y50], [1e5, 1e5], [-1e5, 1e5]]))
    return Scene([Target(1, traj, snr_db=snr_db)], _harbour_platform(), regions=[yellow])


def _clutter(name: str, rng: np.random.Generator, snr_db: float) -> Scene:
    return Scene([])


def _towed(tid: int, start, end, duration: float, rng: np.random.Generator, snr_db: float,
           deviation: float = 0.25) -> Target:
    v = ((end[0] - start[0]) / duration, (end[1] - start[1]) / duration)
    traj = DraggedTrajectory(start, v, rng, deviation_std=deviation, periods=(4.0, 25.0),
                             yaw_offset=float(rng.uniform(0, 2 * math.pi)))
    return Target(tid, traj, shape(FLS_TARGETS[tid]), snr_db)


def _fls(name: str, rng: np.random.Generator, snr_db: float) -> Scene:
    n = int(name[3:])
    dur = scenario_info(name).duration
    near, far = 6.0, 25.0
    if n <= 4:
        targets = [_towed(n, (far, 1.0), (near, -1.0), dur, rng, snr_db)]
    elif n <= 7:
        a, b = {5: (1, 4), 6: (2, 4), 7: (4, 5)}[n]
        targets = [_towed(a, (far, 1.5), (near, 1.5), dur, rng, snr_db),
                   _towed(b, (far, -1.5), (near, -1.5), dur, rng, snr_db)]
    elif n <= 11:
        a, b = {8: (3, 4), 9: (3, 5), 10: (1, 2), 11: (2, 3)}[n]
        targets = [_towed(a, (10.0, -4.0), (22.0, 4.0), dur, rng, snr_db),
                   _towed(b, (22.0, -4.0), (10.0, 4.0), dur, rng, snr_db)]
    elif n == 12:
        targets = [_towed(tid, (far, y), (near, y), dur, rng, snr_db) for tid, y in ((2, 2.5), (3, 0.0), (4, -2.5))]
    elif n == 13:
        targets = [_towed(2, (far, 2.5), (near, 2.5), dur, rng, snr_db),
                   _towed(3, (near, 0.0), (far, 0.0), dur, rng, snr_db),
                   _towed(4, (far, -2.5), (near, -2.5), dur, rng, snr_db)]
    else:
        targets = [_towed(2, (15.0, 0.0), (15.0, 0.0), dur, rng, snr_db, deviation=0.05)]
    return Scene(targets, StaticTrajectory(0.0, 0.0), depth=1.5)


def _sea_trial(name: str, rng: np.random.Generator, snr_db: float) -> Scene:
    auv = ScriptedTrajectory(0.0, 0.0, 0.5, 0.0)
    targets = []
    for tid, start, vel in ((1, (20.0, 8.0), (0.65, -0.08)), (2, (25.0, -8.0), (0.6, 0.08))):
        traj = DraggedTrajectory(start, vel, rng, deviation_std=1.0, periods=(3.0, 30.0),
                                 yaw_offset=float(rng.uniform(0, 2 * math.pi)))
        targets.append(Target(tid, traj, shape('cube' if tid == 1 else 'sphere'), snr_db))
    return Scene(targets, auv, depth=3.0)


_BUILDERS: dict[str, Callable[..., Scene]] = {
    'scenario1': _scenario1, 'scenario2': _scenario2, 'clutter': _clutter, 'sea_trial': _sea_trial,
    'structure_only': _clutter,
}

"""Sensor presets and scenarios.

Sensors: ``harbour`` (ESC paper §2, §5), ``seaking675`` and ``seaking325`` (FLS paper Table 1), and the
multibeam imaging sonars ``oculus_m750d``, ``gemini_720`` and ``aris3000`` (:data:`IMAGING_PRESETS`,
:mod:`.imaging`; each value's reason beside it).

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

Imaging-sonar scenarios (any imaging preset). Each is laid out for a head whose range setting is ``R``
(the preset's ``imaging.range_max``: 30 m on the Oculus and Gemini, 15 m on the ARIS) and whose fan is
``+-H`` (half its ``fov_deg``): positions are given in fan units, range ``rho R`` at bearing ``beta H``,
and every length of the scene (structure, platform path and speed, formations) is scaled by
``s = R / 30 m``, so each head sees the same scene filling its fan; diver and vehicle speeds are real
speeds (on the narrow ARIS fan they cross it in seconds and their loop repeats). Overriding
``imaging.range_max`` does not rescale the scene. SNR is a target's whole echo at its best aspect re the
background at its range (:mod:`.imaging`).

* ``imaging_empty``: static platform, seabed beyond the grazing range, no targets, 600 s: frozen speckle.
* ``imaging_diver``: a diver swimming a loop across and toward the fan (range 0.18-0.85 R: 5-26 m on
  the Oculus) at 0.6-1.5 m/s, turning on arcs of 2 m radius, seen from a hovering platform (a few
  centimetres of drift, half a degree of yaw); SNR 20 dB, so its tank and head cells stand about 10-13 dB
  over the background (at 15 dB, 7-10 dB, single-cell CFAR finds it in about 15 % of the frames). 120 s.
* ``imaging_vehicle``: an ROV-sized vehicle (3.5 m) passing across the fan at 0.45 R and back at
  0.7 R at 1.5 m/s, leaving the fan at each end; SNR 30 dB (its hull cells 20 dB and more over the
  background), with its shadow. 120 s.
* ``imaging_school``: 8 fish (point echoes, SNR 15 dB: at the imaging presets' design P_fa a fish is
  detected in about two frames of three; at 7 dB in one of ten) in two groups of 4 swimming X-shaped
  paths that cross at the centre of the fan at 30 s. 60 s.
* ``imaging_harbour``: a quay wall ahead, a second wall across the path after a 90 deg left turn and two
  rows of piles, passed by the platform at 0.7 s m/s (50 s straight, a 30 s turn at 3 deg/s, 40 s
  straight), with odometry; a diver swims a loop in front of the moving sonar. 120 s.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sonar_tracking.sim.motion import (
    DraggedTrajectory,
    RelativeTrajectory,
    ScriptedTrajectory,
    Segment,
    StaticTrajectory,
    WaypointTrajectory,
)
from sonar_tracking.sim.scene import ClutterRegion, Scene, Target
from sonar_tracking.sim.shapes import shape
from sonar_tracking.sim.structure import (
    HARBOUR_SONAR_XY,
    RoughShape,
    Structure,
    StructureConfig,
    Texture,
    walls_of,
)

__all__ = ['SENSOR_PRESETS', 'IMAGING_PRESETS', 'STRUCTURE_PRESETS', 'SCENARIOS', 'ScenarioInfo', 'scenario_info',
           'build_scene', 'FLS_TARGETS', 'HARBOUR_SONAR_XY', 'imaging_fan']

#: Flat setting overrides of each sensor preset (names as in SimConfig).
SENSOR_PRESETS: dict[str, dict] = {
    'harbour': {},
    'seaking675': {'seaking.frequency_khz': 675.0, 'seaking.beam_width_deg': 1.5,
                   'seaking.vertical_beam_width_deg': 40.0, 'seaking.absorption_db_per_m': 0.2},
    'seaking325': {'seaking.frequency_khz': 325.0, 'seaking.beam_width_deg': 3.0,
                   'seaking.vertical_beam_width_deg': 20.0, 'seaking.absorption_db_per_m': 0.09},
    # Blueprint Subsea Oculus M750d, 750 kHz mode (its data sheet: 512 beams, 130 x 20 deg, 1 deg angular
    # resolution, 4 mm range resolution, 120 m range, up to 40 Hz).
    'oculus_m750d': {
        'imaging.n_beams': 512, 'imaging.fov_deg': 130.0,  # 512 beams over 130 deg: 0.25 deg apart
        'imaging.beam_width_deg': 1.0,        # 1 deg resolution: 4 beams per beam width, neighbours correlated
        'imaging.vertical_beam_width_deg': 20.0,
        'imaging.frequency_khz': 750.0,
        'imaging.pulse_length': 0.004,        # 4 mm range resolution: finer than the bins, which set it
        'imaging.sidelobe_db': -13.26,        # shading unpublished: unshaded, the bright sidelobe arcs of M750d frames
        'imaging.range_min': 0.1,             # the near limit of the range setting
        'imaging.range_max': 30.0,            # of the 120 m: the echo from 30 m is back in 40 ms, so 20 Hz fits
        'imaging.n_bins': 1000,               # 3 cm bins at 30 m; n_bins and n_beams are settings for reduced frames
        'imaging.frame_rate': 20.0,           # up to 40 Hz at ranges within c / 80 Hz = 18.75 m
        'imaging.altitude': 3.0,              # an ROV 3 m off the bottom, head tilted 10 deg down:
        'imaging.tilt_deg': 10.0,             # seabed beyond the grazing range 3 m / sin(20 deg) = 8.8 m
        'imaging.reference_range': 10.0,
        'output.coding': 'db',                # the driver's frames are 8-bit log-compressed counts
    },
    # Tritech Gemini 720-class (the 720is manual: 720 kHz, 1.0 deg acoustic and 0.25 deg effective angular
    # resolution, 20 deg vertical, up to 30 Hz; the 720ik spans 130 deg with 512 beams).
    'gemini_720': {
        'imaging.n_beams': 512, 'imaging.fov_deg': 130.0,
        'imaging.beam_width_deg': 0.5,        # a point echo's width after its processing, between 1.0 and 0.25 deg
        'imaging.vertical_beam_width_deg': 20.0,
        'imaging.frequency_khz': 720.0,
        'imaging.pulse_length': 0.008,        # 8 mm range resolution
        'imaging.sidelobe_db': -20.0,         # shading unpublished: a mildly shaded aperture
        'imaging.range_min': 0.1,
        'imaging.range_max': 30.0,            # of the 120 m, so 20 Hz fits (30 Hz within 25 m)
        'imaging.n_bins': 1000,
        'imaging.frame_rate': 20.0,
        'imaging.altitude': 3.0, 'imaging.tilt_deg': 10.0, 'imaging.reference_range': 10.0,
        'output.coding': 'db',
    },
    # SoundMetrics ARIS Explorer 3000-class acoustic camera (Ocean Networks Canada's instrument page: 128 beams,
    # 28 x 14 deg; DIDSON-class beams 0.3-0.8 deg, frame rates 4-21 Hz by window length), 1.8 MHz mode.
    'aris3000': {
        'imaging.n_beams': 128, 'imaging.fov_deg': 28.0,   # 0.22 deg apart
        'imaging.beam_width_deg': 0.3,        # 0.3 deg at 1.8 MHz (0.25 deg at 3 MHz, to 5 m only)
        'imaging.vertical_beam_width_deg': 14.0,
        'imaging.frequency_khz': 1800.0,
        'imaging.pulse_length': 0.01,         # about a centimetre in a 15 m window
        'imaging.sidelobe_db': -25.0,         # an acoustic lens, not a phased array: low sidelobes (assumed)
        'imaging.range_min': 0.7,             # the shortest window start
        'imaging.range_max': 15.0,            # the 1.8 MHz window
        'imaging.n_bins': 1200,               # 1.2 cm bins: the fine range bins of an acoustic camera
        'imaging.frame_rate': 15.0,           # 15 Hz in a 15 m window
        'imaging.texture_beams': 8,           # 128 beams: blocks of 8 beams (2.4 beam widths)
        'imaging.altitude': 1.5,              # a small ROV or a fixed mount 1.5 m off the bottom, tilted 8 deg:
        'imaging.tilt_deg': 8.0,              # seabed beyond 1.5 m / sin(15 deg) = 5.8 m
        'imaging.reference_range': 5.0,
        'output.coding': 'db',
        'output.db_span': 80.0,               # ARIS samples span about 80 dB (config/sensors/aris_didson.yaml)
    },
}

#: The multibeam imaging sonars (:class:`~sonar_tracking.sim.imaging.ImagingSonar`).
IMAGING_PRESETS = ('oculus_m750d', 'gemini_720', 'aris3000')

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
SCENARIOS.update({
    'imaging_empty': ScenarioInfo('imaging_empty', IMAGING_PRESETS, 600.0, 1.0, 0.0,
                                  description='imaging sonar on a static platform, seabed, no targets: frozen '
                                  'speckle for 10 minutes'),
    'imaging_diver': ScenarioInfo('imaging_diver', IMAGING_PRESETS, 120.0, 1.0, 20.0,
                                  description='a diver swimming across and toward the fan, hovering platform'),
    'imaging_vehicle': ScenarioInfo('imaging_vehicle', IMAGING_PRESETS, 120.0, 1.0, 30.0,
                                    description='a strong vehicle passing across the fan, with its shadow'),
    'imaging_school': ScenarioInfo('imaging_school', IMAGING_PRESETS, 60.0, 1.0, 15.0,
                                   description='two groups of 4 weak fish crossing each other'),
    'imaging_harbour': ScenarioInfo('imaging_harbour', IMAGING_PRESETS, 120.0, 1.0, 20.0,
                                    description='walls and piles passed by a moving, turning platform; one diver'),
})


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
    if base in _IMAGING_BUILDERS:
        scene = _IMAGING_BUILDERS[base](rng, snr_db, *imaging_fan(sensor))
    else:
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


# -- imaging-sonar scenarios ---------------------------------------------------------------------------

#: Range setting the imaging scenes are laid out for [m]; a head of range R scales them by R / this.
IMAGING_SCENE_RANGE = 30.0


def imaging_fan(sensor: str) -> tuple[float, float]:
    """Range setting ``R`` [m] and half field of view ``H`` [rad] of an imaging preset."""
    p = SENSOR_PRESETS[sensor]
    return float(p['imaging.range_max']), math.radians(p['imaging.fov_deg']) / 2


def _fan_point(big_r: float, half: float, rho: float, beta: float) -> tuple[float, float]:
    """The point at range ``rho R`` and bearing ``beta H`` (sensor frame at the origin, looking +x)."""
    return (big_r * rho * math.cos(beta * half), big_r * rho * math.sin(beta * half))


#: A diver's loop in fan units (rho, beta) and its speed on each leg [m/s]: across and toward the fan.
_DIVER_LOOP = ((0.85, -0.7), (0.45, -0.1), (0.18, 0.5), (0.3, 0.8), (0.6, 0.3), (0.75, -0.3))
_DIVER_SPEEDS = (1.0, 1.5, 0.8, 0.6, 1.2, 0.9)
#: A diver turns along an arc of this radius [m], not on the spot: 15-45 deg/s at 0.6-1.5 m/s.
DIVER_TURN_RADIUS = 2.0


def _imaging_empty(rng: np.random.Generator, snr_db: float, big_r: float, half: float) -> Scene:
    return Scene([], StaticTrajectory(0.0, 0.0))


def _imaging_diver(rng: np.random.Generator, snr_db: float, big_r: float, half: float) -> Scene:
    s = big_r / IMAGING_SCENE_RANGE
    hover = DraggedTrajectory((0.0, 0.0), (0.0, 0.0), rng, deviation_std=0.05 * s, periods=(20.0, 60.0),
                              yaw_std=math.radians(0.5))
    path = WaypointTrajectory([_fan_point(big_r, half, *p) for p in _DIVER_LOOP], _DIVER_SPEEDS, DIVER_TURN_RADIUS)
    return Scene([Target(1, path, shape('diver'), snr_db)], hover)


def _imaging_vehicle(rng: np.random.Generator, snr_db: float, big_r: float, half: float) -> Scene:
    # Two passes across the fan, each from beyond one edge to beyond the other (or beyond the range).
    near, far = 0.45 * big_r, 0.7 * big_r
    y_near, y_far = (min(1.15 * x * math.tan(half), 1.3 * big_r) for x in (near, far))
    path = WaypointTrajectory([(near, -y_near), (near, y_near), (far, y_far), (far, -y_far)], 1.5)
    return Scene([Target(1, path, shape('vehicle'), snr_db)], StaticTrajectory(0.0, 0.0))


#: Fish of a group about its centre [m at R = 30 m].
_SCHOOL_FORMATION = ((0.0, 0.0), (0.8, 0.5), (-0.6, 0.7), (0.4, -0.8))


def _imaging_school(rng: np.random.Generator, snr_db: float, big_r: float, half: float) -> Scene:
    s = big_r / IMAGING_SCENE_RANGE
    duration = SCENARIOS['imaging_school'].duration
    centre = np.array([0.5 * big_r, 0.0])
    w = 0.5 * big_r * math.tan(0.5 * half)
    targets = []
    # Group A from near-right to far-left, group B from far-right to near-left: both at the centre at mid-time.
    for g, half_path in enumerate((np.array([0.2 * big_r, w]), np.array([-0.2 * big_r, w]))):
        velocity = 2.0 * half_path / duration
        for k, offset in enumerate(_SCHOOL_FORMATION):
            start = centre - half_path + s * np.asarray(offset)
            traj = DraggedTrajectory(tuple(start), tuple(velocity), rng, deviation_std=0.15 * s, periods=(5.0, 20.0),
                                     yaw_std=math.radians(10.0))
            targets.append(Target(1 + 4 * g + k, traj, shape('fish'), snr_db))
    return Scene(targets, StaticTrajectory(0.0, 0.0))


#: The harbour's walls and pile rows [m at R = 30 m]; the platform starts at the origin heading +x.
IMAGING_HARBOUR_WALLS = (((60.0, -20.0), (60.0, 70.0)), ((5.0, 55.0), (60.0, 55.0)))
IMAGING_HARBOUR_PILES = tuple((x, 4.0) for x in (10.0, 16.0, 22.0, 28.0, 34.0, 40.0)) + \
    tuple((53.0, y) for y in (20.0, 26.0, 32.0, 38.0, 44.0))
_PILE_RADIUS, _PILE_POINTS = 0.15, 8
_HARBOUR_LOCAL_LOOP = ((0.4, -0.5), (0.65, 0.2), (0.5, 0.6), (0.3, 0.0))


def _harbour_structure(rng: np.random.Generator, s: float) -> Structure:
    """Quay walls (rough facet scatterers every 5 cm) and piles (rings of isotropic scatterers)."""
    config = StructureConfig(wall_db=20.0, pile_db=25.0)
    segments = tuple(tuple((s * x, s * y) for x, y in seg) for seg in IMAGING_HARBOUR_WALLS)
    walls = walls_of(segments, 10 ** (config.wall_db / 10), 0.05 * s, 0.05 * s, config.roughness, (0.0, 0.0), rng)
    a = np.linspace(0.0, 2 * math.pi, _PILE_POINTS, endpoint=False)
    ring = _PILE_RADIUS * np.stack([np.cos(a), np.sin(a)], axis=1)
    pts = np.concatenate([s * np.asarray(p) + ring for p in IMAGING_HARBOUR_PILES])
    piles = RoughShape('piles', pts, np.zeros_like(pts), np.full(len(pts), 10 ** (config.pile_db / 10) / _PILE_POINTS),
                       np.ones(len(pts)), float(np.ptp(pts[:, 0]) + np.ptp(pts[:, 1])))
    return Structure(config, walls, piles, Texture(np.zeros((0, 2)), np.zeros(0), 0.0))


def _imaging_harbour(rng: np.random.Generator, snr_db: float, big_r: float, half: float) -> Scene:
    s = big_r / IMAGING_SCENE_RANGE
    platform = ScriptedTrajectory(0.0, 0.0, 0.7 * s, 0.0,
                                  (Segment(50.0), Segment(30.0, math.radians(3.0)), Segment(40.0)))
    local = WaypointTrajectory([_fan_point(big_r, half, *p) for p in _HARBOUR_LOCAL_LOOP], 0.4, DIVER_TURN_RADIUS)
    scene = Scene([Target(1, RelativeTrajectory(platform, local), shape('diver'), snr_db)], platform)
    scene.structure = _harbour_structure(rng, s)
    return scene


_IMAGING_BUILDERS: dict[str, Callable[..., Scene]] = {
    'imaging_empty': _imaging_empty, 'imaging_diver': _imaging_diver, 'imaging_vehicle': _imaging_vehicle,
    'imaging_school': _imaging_school, 'imaging_harbour': _imaging_harbour,
}

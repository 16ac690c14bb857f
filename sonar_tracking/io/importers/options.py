"""Settings of ``sonar_import`` (one frozen Config, so presets and the command line share names)."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from sonar_tracking.core.config import Config, setting
from sonar_tracking.core.intensity import IntensityConfig

__all__ = ['ImportOptions', 'ProjectedOptions', 'ANGLE_UNITS', 'angle_to_rad']

ANGLE_UNITS = ('auto', 'rad', 'deg', 'grad')
_UNIT_RAD = {'rad': 1.0, 'deg': math.pi / 180.0, 'grad': math.pi / 200.0}


def angle_to_rad(value: float, unit: str) -> float:
    """A head angle in ``unit`` (rad, deg, grad) in radians."""
    return float(value) * _UNIT_RAD[unit]


@dataclass(frozen=True)
class ProjectedOptions(Config):
    """How an imaging sonar's ProjectedSonarImage becomes a sector (the importer and the live adapter)."""

    beam_frame: str = setting('auto', 'ProjectedSonarImage: frame of beam_directions; message = z forward, '
                              'x up, y starboard (the definition); rep103 = x forward, y port; auto = rep103 '
                              'when every direction has z = 0', choices=('auto', 'message', 'rep103'))
    image_layout: str = setting('range_major', 'ProjectedSonarImage: order of image.data; range_major = all '
                                'beams of the first range, then the next range (what the drivers and '
                                'sonar_image_proc use); beam_major = all ranges of beam 0 first',
                                choices=('range_major', 'beam_major'))
    head_clockwise: bool = setting(False, 'the head angle (or beam azimuth) grows clockwise seen from above; '
                                   'bearings are then negated to REP-103 (counter-clockwise)')
    decode: bool = setting(False, 'write linear amplitude (32FC1) decoded with intensity.coding; false = keep '
                           'the recorded values and let the front end decode them (its intensity.* settings)')
    frame_id: str = setting('', 'frame_id of the sectors; empty = the recording\'s')
    intensity: IntensityConfig = dataclasses.field(default_factory=IntensityConfig)


@dataclass(frozen=True)
class ImportOptions(ProjectedOptions):
    """How a recording becomes sectors: which topics, which head convention, which intensity coding."""

    topic: str = setting('', 'sonar topic in the source bag; empty = the one recognised sonar topic')
    odometry_topic: str = setting('', 'nav_msgs/Odometry topic in the source bag; empty = the only one, if any; '
                                  '"none" = do not import a pose')
    pings: int = setting(0, 'scanning sonars: pings per sector; 0 = one sector per sweep', low=0, high=100000)
    max_gap: float = setting(2.0, 'scanning sonars: more time than this between two pings ends the sweep and is '
                             'reported', unit='s', low=0.0, low_open=True, high=1e6)
    head_zero_deg: float = setting(0.0, 'scanning sonars: the head angle that points along the sonar x axis '
                                   '(forward), in the recording\'s unit converted to degrees', unit='deg',
                                   low=-720.0, high=720.0)
    angle_unit: str = setting('auto', 'scanning sonars: unit of the head angle in the messages (auto: degrees '
                              'for scan lines, gradians for integer Ping360 angles, else gradians if any '
                              'angle exceeds 2 pi, radians otherwise)', choices=ANGLE_UNITS)
    speed_of_sound: float = setting(1500.0, 'speed of sound for pings that give a sample period but not a range',
                                    unit='m/s', low=1300.0, high=1700.0)

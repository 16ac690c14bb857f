"""Which head and intensity conventions an import applies, and where each came from.

A setting of ``sonar_import`` comes, in this order, from a command-line option, the preset named
with ``--preset``, the sensor the recording names (its message type or its format), or the
default. The conventions a sensor implies are its preset's (``config/sensors/NAME.yaml``, section
``/**/sonar_import:``), so a Tritech scan line imported without ``--preset`` turns clockwise with
180 deg ahead, as with ``--preset micron_seaking``. Only the conventions (:data:`CONVENTIONS`) come
from the sensor; ranges, gaps and topics stay the user's or the defaults.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sonar_tracking.io.importers.options import ImportOptions

__all__ = ['CONVENTIONS', 'PRESET_KEY', 'Sensor', 'SENSORS', 'sensor_named_by', 'load_preset', 'resolve',
           'DEFAULT_SOURCE']

PRESET_KEY = 'sonar_import'

#: Settings a sensor's message type or format decides when neither an option nor the preset does.
CONVENTIONS = ('head_clockwise', 'head_zero_deg', 'angle_unit', 'decode', 'intensity.coding')

DEFAULT_SOURCE = 'default'


@dataclass(frozen=True)
class Sensor:
    """A sonar family: its name, the preset holding its conventions, and the words of a message type
    that name it (matched case-insensitively anywhere in ``package/msg/Name``)."""

    name: str
    preset: str
    words: tuple[str, ...]


SENSORS = (
    Sensor('Tritech Micron/SeaKing', 'micron_seaking', ('tritech', 'micron', 'seaking')),
    Sensor('Ping360', 'ping360', ('ping360',)),
)
TRITECH, PING360 = SENSORS


def sensor_named_by(msgtype: str) -> Sensor | None:
    """The sensor whose name a message type contains (``micron_driver_ros/ScanLine``,
    ``ping360_sonar_msgs/msg/SonarEcho``), or None."""
    low = msgtype.lower()
    for sensor in SENSORS:
        if any(word in low for word in sensor.words):
            return sensor
    return None


def load_preset(name: str) -> dict:
    """The importer settings of a sensor preset (``config/sensors/NAME.yaml``, or a path ending in
    ``.yaml``), section ``/**/sonar_import: ros__parameters:`` (so the file is also a valid ROS
    parameter file for the nodes it configures); ValueError when the section is missing."""
    from sonar_tracking.io import param_files
    from sonar_tracking.resources import config_path
    path = Path(name) if name.endswith('.yaml') else config_path(f'sensors/{name}.yaml')
    section = param_files.parameters_for(param_files.load(path), PRESET_KEY)
    if section is None:
        raise ValueError(f'{path} has no /**/{PRESET_KEY}: ros__parameters: section')
    return section


def resolve(given: dict[str, tuple[Any, str]], sensor: Sensor | None, named_by: str
            ) -> tuple[ImportOptions, dict[str, str]]:
    """The options of an import and the source of each convention.

    ``given`` maps flat setting names to ``(value, source)`` from the options and the preset (the
    options already override the preset). The conventions not given come from ``sensor``'s preset,
    with the source ``named_by`` (how the recording names its sensor); the rest are defaults.
    Returns the options and ``{setting: source}`` for every name of :data:`CONVENTIONS`.
    """
    flat = {name: value for name, (value, _) in given.items()}
    sources = {name: given[name][1] if name in given else DEFAULT_SOURCE for name in CONVENTIONS}
    if sensor is not None:
        implied = load_preset(sensor.preset)
        for name in CONVENTIONS:
            if name not in given and name in implied:
                flat[name] = implied[name]
                sources[name] = f'{named_by}: {sensor.name} (preset {sensor.preset})'
    return ImportOptions.from_flat(flat), sources

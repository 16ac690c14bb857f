"""Message definitions of common sonar drivers, registered with ``rosbags`` at run time (no ROS build).

A bag usually carries its own definitions (ROS 1 connection headers, MCAP schemas, Jazzy sqlite3
bags); those are registered first and win. The texts here are the fallback for bags without them
(older sqlite3 rosbag2 files), written from the field names of the public drivers:

* Tritech Micron / SeaKing scan line (``tritech_micron``, ``micron_driver_ros``, ``provider_sonar``
  drivers): head ``angle`` [deg], ``bin_distance_step`` [m], ``bins`` of ``distance`` + 8-bit
  ``intensity``;
* Ping360 echo of the ``ping360_sonar`` driver (``SonarEcho``: ``angle``, ``range`` [m],
  ``number_of_samples``, ``intensities``; the ROS 1 driver sends gradians, the ROS 2 one radians);
* Ping360 of the ``bluerobotics_sonar`` driver (``SonarPing360``: ``angle`` [grad],
  ``sample_period`` [25 ns ticks], ``profile_data``);
* ``marine_acoustic_msgs/ProjectedSonarImage`` with ``PingInfo`` and ``SonarImageData``.

Importers recognise messages by their fields (:mod:`.ros_bag`), not by these names, so a driver
package with another name but the same fields is read the same way.
"""
from __future__ import annotations

from typing import Any

__all__ = ['BUILTIN_DEFINITIONS', 'register_definitions', 'register_builtin']

_SCANLINE = '''std_msgs/Header header
float32 angle
float32 bin_distance_step
IntensityBin[] bins
'''
_INTENSITY_BIN = '''float32 distance
uint8 intensity
'''
_SONAR_ECHO = '''std_msgs/Header header
float32 angle
uint8 gain
uint16 number_of_samples
uint16 transmit_frequency
uint16 speed_of_sound
uint8 range
uint8[] intensities
'''
_SONAR_PING360 = '''std_msgs/Header header
float32 distance
uint8 mode
uint8 gain_setting
uint16 angle
uint16 transmit_duration
uint16 sample_period
uint16 transmit_frequency
float32 range
uint8[] profile_data
'''
_PROJECTED = '''std_msgs/Header header
PingInfo ping_info
geometry_msgs/Vector3[] beam_directions
float32[] ranges
SonarImageData image
'''
_PING_INFO = '''float32 frequency
float32 sound_speed
float32[] tx_beamwidths
float32[] rx_beamwidths
'''
_IMAGE_DATA = '''bool is_bigendian
uint32 DTYPE_UINT8=0
uint32 DTYPE_INT8=1
uint32 DTYPE_UINT16=2
uint32 DTYPE_INT16=3
uint32 DTYPE_UINT32=4
uint32 DTYPE_INT32=5
uint32 DTYPE_UINT64=6
uint32 DTYPE_INT64=7
uint32 DTYPE_FLOAT32=8
uint32 DTYPE_FLOAT64=9
uint32 dtype
uint32 beam_count
uint8[] data
'''

#: ROS type name -> definition text (dependencies before the types using them).
BUILTIN_DEFINITIONS: dict[str, str] = {
    'tritech_micron/msg/IntensityBin': _INTENSITY_BIN,
    'tritech_micron/msg/ScanLine': _SCANLINE.replace('IntensityBin[]', 'tritech_micron/IntensityBin[]'),
    'ping360_sonar/msg/SonarEcho': _SONAR_ECHO,
    'ping360_sonar_msgs/msg/SonarEcho': _SONAR_ECHO,
    'bluerobotics_sonar_msgs/msg/SonarPing360': _SONAR_PING360,
    'marine_acoustic_msgs/msg/PingInfo': _PING_INFO,
    'marine_acoustic_msgs/msg/SonarImageData': _IMAGE_DATA,
    'marine_acoustic_msgs/msg/ProjectedSonarImage': _PROJECTED.replace(
        'PingInfo ', 'marine_acoustic_msgs/PingInfo ').replace(
        'SonarImageData ', 'marine_acoustic_msgs/SonarImageData '),
}


def register_definitions(typestore: Any, definitions: dict[str, str]) -> list[str]:
    """Register ``{msgtype: msg text}`` with a rosbags typestore; returns the problems (one line each).

    Types the typestore already knows are left alone. A definition that does not parse is
    reported, not raised, so one bad connection does not stop the others.
    """
    from rosbags.typesys import get_types_from_msg
    problems: list[str] = []
    for name, text in definitions.items():
        if name in typestore.types or not text:
            continue
        try:
            typestore.register(get_types_from_msg(text, name))
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for a bad text
            problems.append(f'{name}: definition not understood ({exc})')
    return problems


def register_builtin(typestore: Any) -> None:
    """Register :data:`BUILTIN_DEFINITIONS` that the typestore does not know yet."""
    register_definitions(typestore, BUILTIN_DEFINITIONS)

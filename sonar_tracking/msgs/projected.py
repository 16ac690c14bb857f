"""Imaging-sonar frames as ``marine_acoustic_msgs/ProjectedSonarImage``, the message of imaging-sonar
drivers (Oculus, Gemini, BlueView through their ROS 2 drivers).

The message's frame is z forward, x up, so y is starboard: a beam at REP-103 bearing ``b``
(counter-clockwise from forward) points along ``(0, -sin b, cos b)``. :func:`sector_to_projected`
writes a sector that way, range-major (all beams of a range, then the next) and little-endian, as
the drivers do; ``sonar_import`` and ``projected_sonar_adapter`` read it back into the same sector.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.msgs.stamps import header
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['PROJECTED_TYPE', 'IMAGE_DTYPES', 'DTYPE_CODES', 'sector_to_projected']

PROJECTED_TYPE = 'marine_acoustic_msgs/msg/ProjectedSonarImage'
#: SonarImageData ``dtype`` codes and their element types.
IMAGE_DTYPES: dict[int, type] = {0: np.uint8, 1: np.int8, 2: np.uint16, 3: np.int16, 4: np.uint32, 5: np.int32,
                                 6: np.uint64, 7: np.int64, 8: np.float32, 9: np.float64}
DTYPE_CODES: dict[np.dtype, int] = {np.dtype(t): code for code, t in IMAGE_DTYPES.items()}


def sector_to_projected(values: np.ndarray, geometry: SectorGeometry, stamp_ns: int, frame_id: str,
                        types: MessageTypes | None = None, sound_speed: float = 1500.0, frequency: float = 0.0,
                        beam_width: float = 0.0) -> Any:
    """A ProjectedSonarImage of sector ``values`` (bins x beams, any SonarImageData type) taken with
    ``geometry``; ``frequency`` [Hz] and ``beam_width`` [rad] fill ``ping_info`` (0: unknown)."""
    v = np.asarray(values)
    code = DTYPE_CODES.get(v.dtype.newbyteorder('='))
    if code is None:
        raise ValueError(f'SonarImageData cannot carry {v.dtype} values')
    if v.shape != geometry.shape:
        raise ValueError(f'values of shape {v.shape} do not fit geometry {geometry.shape}')
    types = types or rclpy_types()
    b = geometry.bearings()
    dirs = [types.new('geometry_msgs/msg/Vector3', x=0.0, y=float(-np.sin(a)), z=float(np.cos(a))) for a in b]
    data = np.ascontiguousarray(v.astype(v.dtype.newbyteorder('<'), copy=False)).reshape(-1).view(np.uint8)
    image = types.new('marine_acoustic_msgs/msg/SonarImageData', is_bigendian=False, dtype=code,
                      beam_count=geometry.n_beams, data=types.numeric_sequence(data))
    widths = np.full(geometry.n_beams, beam_width, np.float32)
    info = types.new('marine_acoustic_msgs/msg/PingInfo', frequency=float(frequency), sound_speed=float(sound_speed),
                     tx_beamwidths=types.numeric_sequence(widths), rx_beamwidths=types.numeric_sequence(widths))
    return types.new(PROJECTED_TYPE, header=header(stamp_ns, frame_id, types), ping_info=info, beam_directions=dirs,
                     ranges=types.numeric_sequence(geometry.ranges().astype(np.float32)), image=image)

"""Sector geometry on ``/sonar/sector_info`` (``sensor_msgs/LaserScan``) and sector pairing.

The simulator publishes each sector twice with the same header: the amplitudes as an Image on
``/sonar/sector`` and the geometry as a LaserScan on ``/sonar/sector_info`` (``angle_min`` = bearing
of column 0, ``angle_increment``, ``range_min``/``range_max`` = first/last bin centre,
``time_increment`` = ping period, ``scan_time``; ``ranges``/``intensities`` = strongest return per
beam). Consumers pair the two by stamp with :class:`SectorPairer`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sonar_tracking.core.sector import GeometryError, SectorGeometry
from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.image import image_to_array
from sonar_tracking.msgs.pairing import StampPairer
from sonar_tracking.msgs.stamps import header, header_ns
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['scan_to_geometry', 'geometry_to_scan', 'sector_from_messages', 'SectorPair', 'SectorPairer']


def scan_to_geometry(scan: Any, n_bins: int) -> SectorGeometry:
    """The SectorGeometry described by a LaserScan, for an image of ``n_bins`` rows.

    Raises AdapterError when the scan is inconsistent (no beams, ``angle_max`` not matching
    ``angle_min + (n - 1) * angle_increment``, bad ranges).
    """
    try:
        n_beams = len(scan.ranges)
        angle_min, angle_max = float(scan.angle_min), float(scan.angle_max)
        inc = float(scan.angle_increment)
        geom = SectorGeometry(angle_min=angle_min, angle_increment=inc, n_beams=n_beams,
                              range_min=float(scan.range_min), range_max=float(scan.range_max),
                              n_bins=int(n_bins), ping_period=float(scan.time_increment),
                              scan_time=float(scan.scan_time))
    except AttributeError as exc:
        raise AdapterError(f'not a sensor_msgs/LaserScan: missing field {exc.name!r}') from exc
    except GeometryError as exc:
        raise AdapterError(f'sector geometry: {exc}') from exc
    # LaserScan angles are float32: allow their rounding, not a wrong beam count.
    if abs(geom.angle_max - angle_max) > max(1e-3 * inc, 1e-6 * (1.0 + abs(angle_max))):
        raise AdapterError(f'angle_max = {angle_max:.6f} does not match angle_min + ({n_beams} - 1) * '
                           f'angle_increment = {geom.angle_max:.6f}')
    return geom


def geometry_to_scan(geometry: SectorGeometry, *, amplitudes: np.ndarray | None = None,
                     stamp_ns: int = 0, frame_id: str = '', types: MessageTypes | None = None) -> Any:
    """Build the LaserScan of a sector; ``ranges``/``intensities`` from ``amplitudes`` if given.

    Without amplitudes every beam reports ``inf`` range (no return) and zero intensity.
    """
    if amplitudes is not None:
        ranges, intensities = geometry.strongest_returns(amplitudes)
    else:
        ranges = np.full(geometry.n_beams, np.inf)
        intensities = np.zeros(geometry.n_beams)
    types = types or rclpy_types()
    return types.new(
        'sensor_msgs/msg/LaserScan', header=header(stamp_ns, frame_id, types),
        angle_min=float(geometry.angle_min), angle_max=float(geometry.angle_max),
        angle_increment=float(geometry.angle_increment), time_increment=float(geometry.ping_period),
        scan_time=float(geometry.scan_time), range_min=float(geometry.range_min),
        range_max=float(geometry.range_max),
        ranges=types.numeric_sequence(np.asarray(ranges, np.float32)),
        intensities=types.numeric_sequence(np.asarray(intensities, np.float32)))


def sector_from_messages(image: Any, scan: Any) -> tuple[np.ndarray, SectorGeometry]:
    """Amplitudes and geometry of one sector from its Image and LaserScan.

    Raises AdapterError if the stamps differ or the image shape does not match the geometry.
    """
    if header_ns(image) != header_ns(scan):
        raise AdapterError(f'sector image stamp {header_ns(image)} differs from its geometry stamp '
                           f'{header_ns(scan)}')
    amplitudes = image_to_array(image)
    geom = scan_to_geometry(scan, amplitudes.shape[0])
    if amplitudes.shape[1] != geom.n_beams:
        raise AdapterError(f'sector image has {amplitudes.shape[1]} beams (columns) but its geometry '
                           f'has {geom.n_beams}')
    return amplitudes, geom


@dataclass(frozen=True)
class SectorPair:
    """A sector Image and the LaserScan with the same stamp."""

    stamp_ns: int
    image: Any
    info: Any


class SectorPairer(StampPairer):
    """Pairs sector Images with their LaserScans by exact header stamp (either may come first);
    given-up halves are reported by :meth:`pop_dropped` as ``(stamp_ns, (part,))``."""

    def __init__(self, max_pending: int = 16) -> None:
        super().__init__(('image', 'info'), max_pending)

    def add_image(self, msg: Any) -> SectorPair | None:
        """Offer a sector Image; return the completed pair if its LaserScan is waiting."""
        return self._pair(self.add('image', header_ns(msg), msg))

    def add_info(self, msg: Any) -> SectorPair | None:
        """Offer a sector LaserScan; return the completed pair if its Image is waiting."""
        return self._pair(self.add('info', header_ns(msg), msg))

    @staticmethod
    def _pair(frame: dict | None) -> SectorPair | None:
        return None if frame is None else SectorPair(header_ns(frame['image']), frame['image'], frame['info'])

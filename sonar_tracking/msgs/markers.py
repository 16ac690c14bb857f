"""``visualization_msgs/MarkerArray`` of tracks for RViz.

The array starts with a DELETEALL marker, so tracks that ended disappear, then gives each track
four markers in their own namespaces (toggle them in RViz): a sphere at the position, a label with
the id, a velocity arrow and the position covariance ellipse (a flat cylinder, ``n_sigma``
standard deviations along each principal axis). Confirmed tracks are green, tentative grey.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.stamps import header
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['track_markers', 'covariance_ellipse']

_ARROW, _SPHERE, _CYLINDER, _TEXT = 0, 2, 3, 9
_ADD, _DELETEALL = 0, 3
_NEEDED = ('track_id', 'x', 'y', 'vx', 'vy', 'cov_xx', 'cov_xy', 'cov_yy')


def covariance_ellipse(cov_xx: float, cov_xy: float, cov_yy: float, n_sigma: float = 2.0) -> tuple[float, float, float]:
    """Full axis lengths ``(major, minor)`` and yaw [rad] of the n-sigma ellipse of a 2x2 covariance.

    Negative eigenvalues (a covariance that lost positive definiteness) are clipped to zero.
    """
    cov = np.array([[cov_xx, cov_xy], [cov_xy, cov_yy]], dtype=float)
    vals, vecs = np.linalg.eigh(cov)
    vals = np.clip(vals, 0.0, None)
    yaw = math.atan2(vecs[1, 1], vecs[0, 1])
    return 2.0 * n_sigma * math.sqrt(vals[1]), 2.0 * n_sigma * math.sqrt(vals[0]), yaw


def track_markers(tracks: np.ndarray, *, stamp_ns: int = 0, frame_id: str = 'world', ns: str = 'tracks',
                  scale: float = 1.0, n_sigma: float = 2.0, arrow_seconds: float = 1.0,
                  types: MessageTypes | None = None) -> Any:
    """MarkerArray for a structured array of tracks (``TRACK_DTYPE`` or ``GPF_TRACK_DTYPE``).

    ``scale`` is the sphere diameter [m] (arrow and text sizes follow it); the velocity arrow
    spans ``arrow_seconds`` of motion.
    """
    names = tracks.dtype.names or ()
    missing = [n for n in _NEEDED if n not in names]
    if missing:
        raise AdapterError(f'track records lack field(s) {missing}')
    types = types or rclpy_types()
    hdr = header(stamp_ns, frame_id, types)
    markers = [_marker(types, hdr, ns, 0, _DELETEALL, _SPHERE)]
    confirmed = tracks['confirmed'] if 'confirmed' in names else np.ones(len(tracks), bool)
    for rec, conf in zip(tracks, confirmed):
        tid = int(rec['track_id']) % 2**31
        x, y = float(rec['x']), float(rec['y'])
        vx, vy = float(rec['vx']), float(rec['vy'])
        if not all(map(math.isfinite, (x, y, vx, vy))):
            continue
        color = (0.1, 0.85, 0.2, 1.0) if conf else (0.6, 0.6, 0.6, 0.8)
        markers.append(_marker(types, hdr, f'{ns}/position', tid, _ADD, _SPHERE, pos=(x, y),
                               size=(scale, scale, scale), color=color))
        markers.append(_marker(types, hdr, f'{ns}/label', tid, _ADD, _TEXT, pos=(x, y + scale),
                               size=(0.0, 0.0, scale), color=(1.0, 1.0, 1.0, 1.0), text=f'T{tid}'))
        tip = types.new('geometry_msgs/msg/Point', x=x + vx * arrow_seconds, y=y + vy * arrow_seconds, z=0.0)
        tail = types.new('geometry_msgs/msg/Point', x=x, y=y, z=0.0)
        markers.append(_marker(types, hdr, f'{ns}/velocity', tid, _ADD, _ARROW,
                               size=(0.15 * scale, 0.3 * scale, 0.3 * scale), color=color,
                               points=[tail, tip]))
        major, minor, yaw = covariance_ellipse(float(rec['cov_xx']), float(rec['cov_xy']),
                                               float(rec['cov_yy']), n_sigma)
        if math.isfinite(major) and major > 0.0:
            markers.append(_marker(types, hdr, f'{ns}/covariance', tid, _ADD, _CYLINDER, pos=(x, y),
                                   yaw=yaw, size=(major, max(minor, 1e-3 * major), 0.02 * scale),
                                   color=(color[0], color[1], color[2], 0.3)))
    return types.new('visualization_msgs/msg/MarkerArray', markers=markers)


def _marker(types: MessageTypes, hdr: Any, ns: str, mid: int, action: int, mtype: int, *,
            pos: tuple[float, float] = (0.0, 0.0), yaw: float = 0.0,
            size: tuple[float, float, float] = (1.0, 1.0, 1.0),
            color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
            text: str = '', points: list | None = None) -> Any:
    pose = types.new(
        'geometry_msgs/msg/Pose',
        position=types.new('geometry_msgs/msg/Point', x=pos[0], y=pos[1], z=0.0),
        orientation=types.new('geometry_msgs/msg/Quaternion', x=0.0, y=0.0,
                              z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)))
    return types.new(
        'visualization_msgs/msg/Marker', header=hdr, ns=ns, id=mid, type=mtype, action=action,
        pose=pose, scale=types.new('geometry_msgs/msg/Vector3', x=size[0], y=size[1], z=size[2]),
        color=types.new('std_msgs/msg/ColorRGBA', r=color[0], g=color[1], b=color[2], a=color[3]),
        text=text, points=points or [])

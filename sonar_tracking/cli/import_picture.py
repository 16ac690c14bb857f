"""A picture of a recorded run: the last FLS image with its regions, tracks and the sonar's path.

Reads a bag recorded while a stack processed a recording (``sonar_stack --record``): the last
``/fls/image`` (placed by its ``/fls/image_info``) with the regions of that frame, the ``/gpf/tracks``
and ``/tracks`` positions over the whole run as trails, ``/detections`` as dots and
``/platform/odometry`` as the sonar's path. Whatever of these the bag lacks is left out.

The picture is drawn as ``/sonar/fan`` shows the sonar: forward up, port (+y) to the left. With
odometry in the bag everything is drawn in the sonar's frame at its last pose (metres ahead of it
and to its port side); without, in the frame of the records (for a static sonar, its own). The
image's echo level (dB above the local background) is drawn with the ``viridis`` colour map, with
a colour bar; pixels without data (outside the fan, or masked as structure) in :data:`NO_DATA`, a
grey that is not in the colour map, named in the legend. Each track has a colour of its own and
its id at its last position; its trail is a thin line through points at least
:data:`TRAIL_SPACING` of the tracks' extent apart, so a handful of crossing tracks stay apart; the
legend is below the map, where it hides none of them. The title names the bag and the
time span of its stamps (UTC).
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

import sonar_tracking.msgs as ma
from sonar_tracking.msgs.map_info import fls_image, map_info_to_grid

__all__ = ['draw_run', 'render_run', 'RunPicture', 'NO_DATA', 'COLOUR_MAP', 'ECHO_DB', 'TRAIL_SPACING',
           'thin_trail']

_TYPES = {'/fls/image': 'sensor_msgs/msg/Image', '/fls/image_info': 'nav_msgs/msg/MapMetaData',
          '/fls/regions': 'sensor_msgs/msg/PointCloud2', '/gpf/tracks': 'sensor_msgs/msg/PointCloud2',
          '/tracks': 'sensor_msgs/msg/PointCloud2', '/detections': 'sensor_msgs/msg/PointCloud2',
          '/platform/odometry': 'nav_msgs/msg/Odometry', '/sonar/sector_info': 'sensor_msgs/msg/LaserScan'}
_MAX_SIDE = 800
#: Colour of pixels without data (RGB, 0-1): a neutral grey, which the colour map does not hold.
NO_DATA = (0.80, 0.80, 0.80)
#: The colour map of the echo level, and the level range it spans [dB re background].
COLOUR_MAP = 'viridis'
ECHO_DB = (-3.0, 15.0)
#: Least distance between two drawn points of a track's trail, as a fraction of the tracks' extent.
TRAIL_SPACING = 0.02
#: Track colours, one per track in id order (no grey: that is no data).
_TRACK_COLOURS = ('tab:red', 'tab:orange', 'tab:pink', 'tab:cyan', 'tab:purple', 'tab:brown', 'tab:blue',
                  'tab:green', 'gold', 'black')


@dataclass
class RunPicture:
    """The figure of a run before it is saved; ``view(x, y)`` maps points of the records' frame to
    the axes' coordinates (horizontal: metres to starboard is right, so port +y is left; vertical:
    metres ahead)."""

    fig: Any
    ax: Any
    drawn: dict
    view: Any


def thin_trail(points: np.ndarray, spacing: float) -> np.ndarray:
    """The points of a trail at least ``spacing`` apart from the last kept one (first and last always kept)."""
    if len(points) <= 2 or spacing <= 0:
        return points
    keep = [0]
    for i in range(1, len(points) - 1):
        if math.dist(points[i], points[keep[-1]]) >= spacing:
            keep.append(i)
    keep.append(len(points) - 1)
    return points[keep]


def _frame(path: list) -> Any:
    """Points of the records' frame -> drawn (horizontal, vertical): the sonar's frame at its last pose
    when there is a path, forward up and port to the left."""
    x0, y0, yaw = path[-1] if path else (0.0, 0.0, 0.0)
    c, s = math.cos(yaw), math.sin(yaw)

    def view(x, y):
        dx, dy = np.asarray(x, float) - x0, np.asarray(y, float) - y0
        ahead, port = c * dx + s * dy, -s * dx + c * dy
        return -port, ahead
    return view


def _utc(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9, tz=timezone.utc).strftime('%Y-%m-%d %H:%M:%S')


def render_run(bag: Path) -> RunPicture:
    """The figure of the run in ``bag`` (module docstring), not yet saved."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.patheffects as pe
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch
    from rosbags.typesys import Stores, get_typestore

    from sonar_tracking.io.bags import read_bag
    store = get_typestore(Stores.ROS2_JAZZY)
    images, infos, regions = {}, {}, {}
    trails: dict[str, dict[int, list]] = {'/gpf/tracks': defaultdict(list), '/tracks': defaultdict(list)}
    detections, path, stamps = [], [], []
    for m in read_bag(bag, list(_TYPES)):
        msg = store.deserialize_cdr(m.data, _TYPES[m.topic])
        if m.topic == '/fls/image_info':
            infos[ma.stamp_to_ns(msg.map_load_time)] = msg
            continue
        stamp = ma.header_ns(msg)
        stamps.append(stamp)
        if m.topic == '/fls/image':
            images = {stamp: msg}          # only the last image is drawn
        elif m.topic == '/fls/regions':
            regions[stamp] = ma.cloud_to_array(msg)
        elif m.topic in trails:
            rec = ma.cloud_to_array(msg)
            key = 'track_id' if 'track_id' in rec.dtype.names else rec.dtype.names[0]
            for r in rec:
                trails[m.topic][int(r[key])].append((r['x'], r['y']))
        elif m.topic == '/detections':
            rec = ma.cloud_to_array(msg)
            detections += list(zip(rec['x'], rec['y']))
        elif m.topic == '/platform/odometry':
            path.append(ma.odometry_to_pose(msg))
    view = _frame(path)
    fig, ax = plt.subplots(figsize=(8, 8.6), dpi=110, layout='constrained')
    ax.set_facecolor(NO_DATA)          # beyond the image there is no data either
    drawn = {'image': 0, 'regions': 0, 'gpf_tracks': len(trails['/gpf/tracks']), 'tracks': len(trails['/tracks']),
             'detections': len(detections), 'poses': len(path)}
    handles = []
    for stamp, img in images.items():
        info = infos.get(stamp)
        if info is None:
            continue
        grid = map_info_to_grid(info)
        a = fls_image(img, grid.shape)
        step = max(1, int(np.ceil(max(a.shape) / _MAX_SIDE)))
        a = a[::step, ::step]
        rows = np.arange(a.shape[0] + 1) * step - 0.5
        cols = np.arange(a.shape[1] + 1) * step - 0.5
        h, v = view(*grid.pixel_to_point(rows[:, None], cols[None, :]))
        shown = np.where(a > 0, 10 * np.log10(np.maximum(a, 1e-6)), np.nan)
        cmap = plt.get_cmap(COLOUR_MAP).with_extremes(bad=NO_DATA)
        mesh = ax.pcolormesh(h, v, shown, cmap=cmap, vmin=ECHO_DB[0], vmax=ECHO_DB[1], shading='flat')
        fig.colorbar(mesh, ax=ax, shrink=0.7, label='echo level [dB above the local background]')
        handles.append(Patch(facecolor=NO_DATA, edgecolor='0.5', label='no data'))
        drawn['image'] = 1
        reg = regions.get(stamp)
        if reg is not None and len(reg):
            rh, rv = view(reg['x'], reg['y'])
            handles.append(ax.scatter(rh, rv, s=60, facecolors='none', edgecolors='magenta',
                                      label='regions (last image)'))
            drawn['regions'] = len(reg)
    if detections:
        d = np.array(detections)
        dh, dv = view(d[:, 0], d[:, 1])
        handles.append(ax.scatter(dh, dv, s=2, c='tab:blue', alpha=0.3, label='detections'))
    if path:
        p = np.array(path)
        ph, pv = view(p[:, 0], p[:, 1])
        handles += ax.plot(ph, pv, 'c--', lw=1, label='sonar path')
        handles += ax.plot(ph[-1], pv[-1], 'c^', ms=8, label='sonar (last pose)')
    _draw_trails(ax, trails, view, handles, pe)
    ax.set_aspect('equal')
    ax.set_xlabel('to starboard [m]  (port is left)')
    ax.set_ylabel('ahead [m]' + (' of the sonar at its last pose' if path else ''))
    span = (f'{_utc(min(stamps))} to {_utc(max(stamps))} UTC ({(max(stamps) - min(stamps)) / 1e9:.1f} s)'
            if stamps else 'no stamped messages')
    ax.set_title(f'{Path(bag).name}: {span}', fontsize=10)
    if handles:   # below the map, where it hides nothing
        fig.legend(handles=handles, loc='outside lower center', ncol=4, fontsize=7, frameon=False)
    return RunPicture(fig, ax, drawn, view)


def _draw_trails(ax, trails: dict, view, handles: list, pe) -> None:
    """Each track's thinned trail in a colour of its own, with its id at its last position."""
    tracks = [(topic, tid, np.array(pts)) for topic in ('/gpf/tracks', '/tracks')
              for tid, pts in sorted(trails[topic].items())]
    if not tracks:
        return
    drawn = [np.column_stack(view(p[:, 0], p[:, 1])) for _, _, p in tracks]
    extent = np.concatenate(drawn)
    size = float(max(np.ptp(extent[:, 0]), np.ptp(extent[:, 1]), 1.0))
    halo = [pe.withStroke(linewidth=3.2, foreground='white')]
    for k, ((topic, tid, _), pts) in enumerate(zip(tracks, drawn)):
        colour = _TRACK_COLOURS[k % len(_TRACK_COLOURS)]
        thin = thin_trail(pts, TRAIL_SPACING * size)
        line, = ax.plot(thin[:, 0], thin[:, 1], '-' if topic == '/gpf/tracks' else '--', color=colour, lw=1.8,
                        path_effects=halo, label=f'{topic} {tid}' if len(tracks) <= len(_TRACK_COLOURS) else None)
        ax.plot(thin[-1, 0], thin[-1, 1], 'o', color=colour, ms=4, mec='white', mew=0.8)
        ax.annotate(str(tid), thin[-1], xytext=(4, 4), textcoords='offset points', color=colour, fontsize=9,
                    fontweight='bold', path_effects=halo)
        if line.get_label() and not line.get_label().startswith('_'):
            handles.append(line)


def draw_run(bag: Path, png: Path) -> dict:
    """Draw the run in ``bag`` into ``png``; returns counts of what was drawn."""
    import matplotlib.pyplot as plt
    picture = render_run(bag)
    picture.fig.savefig(png)
    plt.close(picture.fig)
    return picture.drawn

"""A picture of a recorded run: the last FLS image with its regions, tracks and the sonar's path.

Reads a bag recorded while a stack processed a recording (``sonar_stack --record``): the last
``/fls/image`` (placed by its ``/fls/image_info``) with the regions of that frame, the ``/gpf/tracks``
and ``/tracks`` positions over the whole run as trails, ``/detections`` as dots and
``/platform/odometry`` as the sonar's path. Whatever of these the bag lacks is left out.
"""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

import sonar_tracking.msgs as ma
from sonar_tracking.msgs.map_info import fls_image, map_info_to_grid

__all__ = ['draw_run']

_TYPES = {'/fls/image': 'sensor_msgs/msg/Image', '/fls/image_info': 'nav_msgs/msg/MapMetaData',
          '/fls/regions': 'sensor_msgs/msg/PointCloud2', '/gpf/tracks': 'sensor_msgs/msg/PointCloud2',
          '/tracks': 'sensor_msgs/msg/PointCloud2', '/detections': 'sensor_msgs/msg/PointCloud2',
          '/platform/odometry': 'nav_msgs/msg/Odometry'}
_MAX_SIDE = 800


def draw_run(bag: Path, png: Path) -> dict:
    """Draw the run in ``bag`` into ``png``; returns counts of what was drawn."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from rosbags.typesys import Stores, get_typestore

    from sonar_tracking.io.bags import read_bag
    store = get_typestore(Stores.ROS2_JAZZY)
    images, infos, regions = {}, {}, {}
    trails: dict[str, dict[int, list]] = {'/gpf/tracks': defaultdict(list), '/tracks': defaultdict(list)}
    detections, path = [], []
    for m in read_bag(bag, list(_TYPES)):
        msg = store.deserialize_cdr(m.data, _TYPES[m.topic])
        if m.topic == '/fls/image':
            images = {ma.header_ns(msg): msg}          # only the last image is drawn
        elif m.topic == '/fls/image_info':
            infos[ma.stamp_to_ns(msg.map_load_time)] = msg
        elif m.topic == '/fls/regions':
            regions[ma.header_ns(msg)] = ma.cloud_to_array(msg)
        elif m.topic in trails:
            rec = ma.cloud_to_array(msg)
            key = 'track_id' if 'track_id' in rec.dtype.names else rec.dtype.names[0]
            for r in rec:
                trails[m.topic][int(r[key])].append((r['x'], r['y']))
        elif m.topic == '/detections':
            rec = ma.cloud_to_array(msg)
            detections += list(zip(rec['x'], rec['y']))
        else:
            path.append(ma.odometry_to_pose(msg)[:2])
    fig, ax = plt.subplots(figsize=(8, 8))
    drawn = {'image': 0, 'regions': 0, 'gpf_tracks': len(trails['/gpf/tracks']), 'tracks': len(trails['/tracks']),
             'detections': len(detections), 'poses': len(path)}
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
        x, y = grid.pixel_to_point(rows[:, None], cols[None, :])
        shown = np.where(a > 0, 10 * np.log10(np.maximum(a, 1e-6)), np.nan)
        mesh = ax.pcolormesh(x, y, shown, cmap='gray', vmin=-3, vmax=15, shading='flat')
        fig.colorbar(mesh, ax=ax, shrink=0.7, label='dB re background')
        drawn['image'] = 1
        reg = regions.get(stamp)
        if reg is not None and len(reg):
            ax.scatter(reg['x'], reg['y'], s=60, facecolors='none', edgecolors='orange', label='regions (last image)')
            drawn['regions'] = len(reg)
    if detections:
        d = np.array(detections)
        ax.scatter(d[:, 0], d[:, 1], s=2, c='tab:blue', alpha=0.3, label='detections')
    for topic, colour in (('/gpf/tracks', 'tab:red'), ('/tracks', 'tab:green')):
        for k, (tid, pts) in enumerate(sorted(trails[topic].items())):
            p = np.array(pts)
            ax.plot(p[:, 0], p[:, 1], '-', color=colour, lw=1.5, label=f'{topic}' if k == 0 else None)
            ax.annotate(str(tid), p[-1], color=colour, fontsize=8)
    if path:
        p = np.array(path)
        ax.plot(p[:, 0], p[:, 1], 'c--', lw=1, label='sonar path')
        ax.plot(p[-1, 0], p[-1, 1], 'c^', ms=8, label='sonar (last pose)')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_title(Path(bag).name)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc='upper right', fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return drawn

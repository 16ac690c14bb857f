"""Adapter conversions against a plain per-element Python loop (issue: foundation).

Inputs: a 512 x 512 ``32FC1`` sector image and a 10,000-record ``/tracks`` cloud, as rclpy
messages (the nodes' case).
"""
from __future__ import annotations

import struct

import numpy as np

from sonar_tracking.cli.bench import Case, register

_SHAPE = (512, 512)
_N_RECORDS = 10_000


def _image() -> np.ndarray:
    return np.random.default_rng(1).exponential(1.0, _SHAPE).astype(np.float32)


def _records() -> np.ndarray:
    from sonar_tracking.msgs import TRACK_DTYPE
    rng = np.random.default_rng(2)
    r = np.zeros(_N_RECORDS, TRACK_DTYPE)
    for name in TRACK_DTYPE.names:
        r[name] = rng.integers(0, 200, _N_RECORDS) if TRACK_DTYPE[name].kind in 'ui' else rng.normal(size=_N_RECORDS)
    return r


def _image_to_array():
    from sonar_tracking.msgs import array_to_image, image_to_array
    msg = array_to_image(_image())
    return lambda: image_to_array(msg)


def _image_to_array_loop():
    from sonar_tracking.msgs import array_to_image
    msg = array_to_image(_image())

    def convert():
        data, step, h, w = bytes(msg.data), msg.step, msg.height, msg.width
        return np.array([[struct.unpack_from('<f', data, r * step + 4 * c)[0] for c in range(w)]
                         for r in range(h)], dtype=np.float32)
    return convert


def _array_to_image():
    from sonar_tracking.msgs import array_to_image
    img = _image()
    return lambda: array_to_image(img)


def _array_to_image_loop():
    from sensor_msgs.msg import Image
    img = _image()

    def convert():
        buf = bytearray()
        for row in img.tolist():
            for v in row:
                buf += struct.pack('<f', v)
        return Image(height=img.shape[0], width=img.shape[1], encoding='32FC1', step=4 * img.shape[1],
                     data=bytes(buf))
    return convert


def _cloud_to_array():
    from sonar_tracking.msgs import array_to_cloud, cloud_to_array
    msg = array_to_cloud(_records())
    return lambda: cloud_to_array(msg)


def _cloud_layout(msg):
    codes = {2: 'B', 6: 'I', 7: 'f', 8: 'd'}
    return [(f.name, f.offset, '<' + codes[f.datatype]) for f in msg.fields]


def _cloud_to_array_loop():
    from sonar_tracking.msgs import TRACK_DTYPE, array_to_cloud
    msg = array_to_cloud(_records())

    def convert():
        data, step, layout = bytes(msg.data), msg.point_step, _cloud_layout(msg)
        rows = [tuple(struct.unpack_from(fmt, data, i * step + off)[0] for _, off, fmt in layout)
                for i in range(msg.width)]
        return np.array(rows, dtype=TRACK_DTYPE)
    return convert


def _array_to_cloud():
    from sonar_tracking.msgs import array_to_cloud
    recs = _records()
    return lambda: array_to_cloud(recs)


def _array_to_cloud_loop():
    from sensor_msgs.msg import PointCloud2

    from sonar_tracking.msgs import array_to_cloud
    recs = _records()
    template = array_to_cloud(recs[:1])
    layout = _cloud_layout(template)

    def convert():
        step = template.point_step
        buf = bytearray(step * len(recs))
        for i, rec in enumerate(recs.tolist()):
            for (_, off, fmt), v in zip(layout, rec):
                struct.pack_into(fmt, buf, i * step + off, v)
        return PointCloud2(height=1, width=len(recs), fields=template.fields, point_step=step,
                           row_step=step * len(recs), data=bytes(buf), is_dense=True)
    return convert


_MS = 1e-3
for _name, _make, _desc, _limit in [
        ('adapters.image_to_array', _image_to_array, 'Image 512x512 32FC1 -> numpy view', _MS),
        ('adapters.array_to_image', _array_to_image, 'numpy 512x512 float32 -> Image', _MS),
        ('adapters.cloud_to_array', _cloud_to_array, 'PointCloud2 10,000 tracks -> structured array', _MS),
        ('adapters.array_to_cloud', _array_to_cloud, 'structured array 10,000 tracks -> PointCloud2', _MS)]:
    register(Case(name=_name + '.loop', group='adapters', make=globals()[f'{_make.__name__}_loop'],
                  description=_desc + ' (per-element Python loop)', repeats=3, min_time=0.0))
    register(Case(name=_name, group='adapters', make=_make, description=_desc, compare_to=_name + '.loop',
                  limit_s=_limit))

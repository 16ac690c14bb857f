"""``sensor_msgs/PointCloud2`` <-> numpy structured arrays, for any record dtype.

A cloud's ``fields`` (name, offset, datatype, count) map one to one onto a numpy structured dtype
with explicit offsets and ``itemsize = point_step``; ``count > 1`` becomes a sub-array field.
Reading returns a read-only view of ``data`` (rows with padding in ``row_step`` included);
writing packs the array little-endian, height 1 for a 1-D array. A width-0 cloud round-trips
with its fields, so "no records" stays distinguishable from "no message" (DESIGN §4).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.image import buffer_view
from sonar_tracking.msgs.stamps import header
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['DATATYPES', 'dtype_to_fields', 'fields_to_dtype', 'cloud_to_array', 'array_to_cloud']

#: PointField datatype constants -> numpy base type (sensor_msgs/PointField).
DATATYPES: dict[int, np.dtype] = {
    1: np.dtype('i1'), 2: np.dtype('u1'), 3: np.dtype('i2'), 4: np.dtype('u2'),
    5: np.dtype('i4'), 6: np.dtype('u4'), 7: np.dtype('f4'), 8: np.dtype('f8'),
}
_CODES = {(dt.kind, dt.itemsize): code for code, dt in DATATYPES.items()}


def _structured_fields(dtype: np.dtype) -> list[tuple[str, np.dtype, int]]:
    """``(name, field dtype, offset)`` of every field of a structured dtype, in order; AdapterError
    for a dtype without named fields."""
    fields = dtype.fields
    if dtype.names is None or fields is None:
        raise AdapterError(f'a point cloud needs a structured dtype with named fields, got {dtype}')
    return [(name, fields[name][0], int(fields[name][1])) for name in dtype.names]


def dtype_to_fields(dtype: np.dtype) -> list[tuple[str, int, int, int]]:
    """``[(name, offset, datatype, count), ...]`` for a structured dtype of numeric fields."""
    out = []
    for name, ftype, offset in _structured_fields(np.dtype(dtype)):
        base, shape = ftype.base, ftype.shape
        count = int(np.prod(shape)) if shape else 1
        code = _CODES.get((base.kind, base.itemsize))
        if code is None or base.names is not None:
            raise AdapterError(f'field {name!r} has dtype {ftype}, which PointField cannot hold '
                               '(int8/16/32, uint8/16/32, float32/64 and fixed arrays of them)')
        if len(shape) > 1:
            raise AdapterError(f'field {name!r} has a multi-dimensional shape {shape}')
        out.append((name, int(offset), code, count))
    return out


def fields_to_dtype(fields: Sequence[Any], point_step: int, is_bigendian: bool = False) -> np.dtype:
    """The structured dtype of a cloud's ``fields`` (PointField messages or 4-tuples)."""
    names, formats, offsets = [], [], []
    order: Literal['<', '>'] = '>' if is_bigendian else '<'
    for f in fields:
        try:
            name, offset, datatype, count = (f if isinstance(f, tuple) else
                                             (f.name, f.offset, f.datatype, f.count))
        except AttributeError as exc:
            raise AdapterError(f'not a sensor_msgs/PointField: {f!r}') from exc
        base = DATATYPES.get(int(datatype))
        if base is None:
            raise AdapterError(f'field {name!r} has unknown PointField datatype {datatype}')
        if int(count) < 1:
            raise AdapterError(f'field {name!r} has count {count}; it must be >= 1')
        if name in names:
            raise AdapterError(f'field {name!r} appears twice')
        base = base.newbyteorder(order)
        fmt = base if int(count) == 1 else np.dtype((base, (int(count),)))
        if int(offset) < 0 or int(offset) + fmt.itemsize > point_step:
            raise AdapterError(f'field {name!r} at offset {offset} ({fmt.itemsize} bytes) does not fit '
                               f'in point_step {point_step}')
        names.append(name)
        formats.append(fmt)
        offsets.append(int(offset))
    spans = sorted(zip(offsets, (f.itemsize for f in formats), names))
    for (o1, s1, n1), (o2, _, n2) in zip(spans, spans[1:]):
        if o1 + s1 > o2:
            raise AdapterError(f'fields {n1!r} and {n2!r} overlap')
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets, 'itemsize': point_step})


def cloud_to_array(msg: Any) -> np.ndarray:
    """Return the cloud's records: shape (width,) for height 1, else (height, width).

    The result is a read-only view of ``msg.data`` (fields in the cloud's byte order). Raises
    AdapterError for unknown datatypes, overlapping fields, a ``row_step`` shorter than a row,
    or ``data`` shorter than ``row_step * height``.
    """
    try:
        height, width = int(msg.height), int(msg.width)
        point_step, row_step = int(msg.point_step), int(msg.row_step)
        fields, bigendian, data = msg.fields, bool(msg.is_bigendian), msg.data
    except AttributeError as exc:
        raise AdapterError(f'not a sensor_msgs/PointCloud2: missing field {exc.name!r}') from exc
    if point_step <= 0:
        raise AdapterError(f'point_step = {point_step} must be > 0')
    dtype = fields_to_dtype(fields, point_step, bigendian)
    if height < 0 or width < 0:
        raise AdapterError(f'negative cloud size {height} x {width}')
    if width > 0 and row_step < width * point_step:
        raise AdapterError(f'row_step = {row_step} is shorter than {width} points of {point_step} bytes')
    raw = buffer_view(data)
    need = row_step * height if width > 0 else 0
    if raw.size < need:
        raise AdapterError(f'data is short: {raw.size} bytes for {height} rows of row_step {row_step} '
                           f'({need} bytes)')
    if width == 0 or height == 0:
        arr = np.zeros(0 if height <= 1 else (height, 0), dtype=dtype)
    else:
        rows = raw[:need].reshape(height, row_step)[:, :width * point_step]
        arr = rows.view(dtype)
        if height == 1:
            arr = arr.reshape(width)
    arr.flags.writeable = False
    return arr


def array_to_cloud(array: np.ndarray, *, stamp_ns: int = 0, frame_id: str = '',
                   types: MessageTypes | None = None) -> Any:
    """Build a little-endian PointCloud2 from a 1-D (height 1) or 2-D structured array."""
    a = np.asarray(array)
    fields = dtype_to_fields(a.dtype)
    if a.ndim == 1:
        height, width = 1, a.shape[0]
    elif a.ndim == 2:
        height, width = a.shape
    else:
        raise AdapterError(f'a point cloud array must be 1-D or 2-D, got shape {a.shape}')
    le = _little_endian(a.dtype)
    if le != a.dtype:
        a = a.astype(le)
    a = np.ascontiguousarray(a)
    types = types or rclpy_types()
    pf = [types.new('sensor_msgs/msg/PointField', name=n, offset=o, datatype=d, count=c)
          for n, o, d, c in fields]
    floats = [n for n, ftype, _ in _structured_fields(a.dtype) if ftype.base.kind == 'f']
    dense = all(np.isfinite(a[n]).all() for n in floats)
    return types.new(
        'sensor_msgs/msg/PointCloud2', header=header(stamp_ns, frame_id, types), height=height,
        width=width, fields=pf, is_bigendian=False, point_step=a.dtype.itemsize,
        row_step=a.dtype.itemsize * width, data=types.numeric_sequence(a.reshape(-1).view(np.uint8)),
        is_dense=bool(dense))


def _little_endian(dtype: np.dtype) -> np.dtype:
    names, formats, offsets = [], [], []
    for name, ftype, offset in _structured_fields(dtype):
        base = ftype.base.newbyteorder('<')
        names.append(name)
        formats.append(base if not ftype.shape else np.dtype((base, ftype.shape)))
        offsets.append(offset)
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets, 'itemsize': dtype.itemsize})

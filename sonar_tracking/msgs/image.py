"""``sensor_msgs/Image`` <-> numpy for single-channel sonar images.

Supported encodings: ``mono8``/``8UC1`` (uint8), ``mono16``/``16UC1`` (uint16), ``32FC1``
(float32). Reading returns a read-only view of the message buffer whenever the byte order is the
machine's (no copy), honouring row padding in ``step``; writing produces a packed image in the
machine's byte order.
"""
from __future__ import annotations

import sys
from typing import Any

import numpy as np

from sonar_tracking.msgs.errors import AdapterError
from sonar_tracking.msgs.stamps import header
from sonar_tracking.msgs.types import MessageTypes, rclpy_types

__all__ = ['ENCODING_DTYPES', 'image_to_array', 'array_to_image', 'buffer_view']

ENCODING_DTYPES: dict[str, np.dtype] = {
    'mono8': np.dtype(np.uint8),
    '8UC1': np.dtype(np.uint8),
    'mono16': np.dtype(np.uint16),
    '16UC1': np.dtype(np.uint16),
    '32FC1': np.dtype(np.float32),
}
_DEFAULT_ENCODING = {np.dtype(np.uint8): 'mono8', np.dtype(np.uint16): 'mono16',
                     np.dtype(np.float32): '32FC1'}
_LITTLE = sys.byteorder == 'little'


def buffer_view(data: Any) -> np.ndarray:
    """A flat uint8 view of a message's ``data`` (array.array, bytes, numpy array or list)."""
    if isinstance(data, np.ndarray):
        return data.reshape(-1).view(np.uint8) if data.dtype.itemsize == 1 else data.view(np.uint8).reshape(-1)
    try:
        return np.frombuffer(data, dtype=np.uint8)
    except TypeError:
        try:
            return np.asarray(data, dtype=np.uint8).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise AdapterError(f'data of type {type(data).__name__} is not a byte buffer') from exc


def image_to_array(msg: Any) -> np.ndarray:
    """Return the image as a 2-D array ``(height, width)`` of the encoding's dtype.

    The array is a read-only view of ``msg.data`` when no byte swap is needed. Raises
    AdapterError for an unsupported encoding, zero size, a ``step`` shorter than a row, or
    ``data`` whose length is not ``step * height``.
    """
    try:
        enc, height, width, step = msg.encoding, int(msg.height), int(msg.width), int(msg.step)
        bigendian = bool(msg.is_bigendian)
        data = msg.data
    except AttributeError as exc:
        raise AdapterError(f'not a sensor_msgs/Image: missing field {exc.name!r}') from exc
    dtype = ENCODING_DTYPES.get(enc)
    if dtype is None:
        raise AdapterError(f'unsupported image encoding {enc!r}; expected one of {sorted(ENCODING_DTYPES)}')
    if height <= 0 or width <= 0:
        raise AdapterError(f'image has zero size ({height} x {width})')
    row_bytes = width * dtype.itemsize
    if step < row_bytes:
        raise AdapterError(f'step = {step} is shorter than a row of {width} x {enc} ({row_bytes} bytes)')
    if dtype.itemsize > 1 and step % dtype.itemsize:
        raise AdapterError(f'step = {step} is not a multiple of the {dtype.itemsize}-byte pixel size of {enc}')
    raw = buffer_view(data)
    if raw.size < step * height:
        raise AdapterError(f'data is short: {raw.size} bytes for {height} rows of step {step} '
                           f'({step * height} bytes)')
    if raw.size != step * height:
        raise AdapterError(f'data has {raw.size} bytes but step * height = {step * height}')
    swap = dtype.itemsize > 1 and bigendian == _LITTLE
    dt = dtype.newbyteorder('>' if bigendian else '<') if dtype.itemsize > 1 else dtype
    # A row-padded view: only the last axis must be contiguous for the dtype view (numpy >= 1.23).
    arr = raw.reshape(height, step)[:, :row_bytes].view(dt)
    if swap:
        return arr.astype(dtype)
    arr = arr.view()
    arr.flags.writeable = False
    return arr


def array_to_image(array: np.ndarray, encoding: str | None = None, *, stamp_ns: int = 0,
                   frame_id: str = '', types: MessageTypes | None = None) -> Any:
    """Build an Image from a 2-D array.

    ``encoding`` defaults from the dtype (uint8 -> mono8, uint16 -> mono16, float32 -> 32FC1).
    With an explicit encoding the array is cast only where the cast is of the same kind
    (float64 -> 32FC1 is allowed; float -> mono8 is refused).
    """
    a = np.asarray(array)
    if a.ndim != 2:
        raise AdapterError(f'an image needs a 2-D array, got shape {a.shape}')
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise AdapterError(f'image has zero size {a.shape}')
    if encoding is None:
        encoding = _DEFAULT_ENCODING.get(a.dtype.newbyteorder('='))
        if encoding is None:
            raise AdapterError(f'no image encoding for dtype {a.dtype}; pass encoding= or convert to '
                               'uint8, uint16 or float32')
    dtype = ENCODING_DTYPES.get(encoding)
    if dtype is None:
        raise AdapterError(f'unsupported image encoding {encoding!r}; expected one of {sorted(ENCODING_DTYPES)}')
    if a.dtype != dtype:
        if not np.can_cast(a.dtype, dtype, casting='same_kind'):
            raise AdapterError(f'cannot store dtype {a.dtype} as {encoding} without changing its kind')
        a = a.astype(dtype)
    a = np.ascontiguousarray(a)
    types = types or rclpy_types()
    return types.new(
        'sensor_msgs/msg/Image', header=header(stamp_ns, frame_id, types), height=a.shape[0],
        width=a.shape[1], encoding=encoding, is_bigendian=0 if _LITTLE else 1,
        step=a.shape[1] * dtype.itemsize, data=types.numeric_sequence(a.reshape(-1).view(np.uint8)))

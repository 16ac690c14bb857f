"""Where message classes come from: rclpy's generated packages or a ``rosbags`` typestore.

Reading a message only touches fields by name, so it works on either kind. Building one needs
classes and array representations, which differ: rclpy messages hold ``array.array`` (filled
from bytes with one copy), rosbags dataclasses hold numpy arrays and need every field given.
``MessageTypes.new(name, **fields)`` hides the difference.
"""
from __future__ import annotations

import importlib
from typing import Any

import numpy as np

__all__ = ['MessageTypes', 'RclpyTypes', 'RosbagsTypes', 'rclpy_types']


class MessageTypes:
    """Builds messages by ROS type name (``'sensor_msgs/msg/Image'``)."""

    def new(self, msgtype: str, /, **fields: Any) -> Any:
        """Return a message of type ``msgtype`` with ``fields`` set and every other field default."""
        raise NotImplementedError

    def numeric_sequence(self, values: np.ndarray) -> Any:
        """Value for a numeric sequence field (``uint8[] data``, ``float32[] ranges``...).

        ``values`` must already have the field's element dtype.
        """
        raise NotImplementedError


class RclpyTypes(MessageTypes):
    """Message classes from the rclpy message packages (imported on first use)."""

    def __init__(self) -> None:
        self._classes: dict[str, type] = {}

    def cls(self, name: str) -> type:
        """The generated class for ``pkg/msg/Type``."""
        c = self._classes.get(name)
        if c is None:
            pkg, kind, typ = name.split('/')
            c = getattr(importlib.import_module(f'{pkg}.{kind}'), typ)
            self._classes[name] = c
        return c

    def new(self, msgtype: str, /, **fields: Any) -> Any:
        return self.cls(msgtype)(**fields)

    def numeric_sequence(self, values: np.ndarray) -> Any:
        # The generated setters turn bytes into array.array with one memcpy (array.frombytes);
        # a numpy array or list would be walked element by element.
        return np.ascontiguousarray(values).tobytes()


_BASE_DTYPES = {
    'bool': np.bool_, 'byte': np.uint8, 'octet': np.uint8, 'char': np.uint8,
    'int8': np.int8, 'uint8': np.uint8, 'int16': np.int16, 'uint16': np.uint16,
    'int32': np.int32, 'uint32': np.uint32, 'int64': np.int64, 'uint64': np.uint64,
    'float32': np.float32, 'float64': np.float64,
}


class RosbagsTypes(MessageTypes):
    """Message classes of a ``rosbags`` typestore (dataclasses with numpy arrays)."""

    def __init__(self, typestore: Any) -> None:
        self.typestore = typestore

    def new(self, msgtype: str, /, **fields: Any) -> Any:
        _, defs = self.typestore.fielddefs[msgtype]
        values = {}
        for fname, desc in defs:
            values[fname] = fields.pop(fname) if fname in fields else self._default(desc)
        if fields:
            raise TypeError(f'{msgtype} has no field(s) {sorted(fields)}')
        return self.typestore.types[msgtype](**values)

    def numeric_sequence(self, values: np.ndarray) -> Any:
        return np.ascontiguousarray(values)

    def _default(self, desc: tuple) -> Any:
        kind, spec = desc
        kind = int(kind)
        if kind == 1:  # BASE
            typ = spec[0]
            if typ == 'string':
                return ''
            if typ == 'bool':
                return False
            return _BASE_DTYPES[typ](0).item()
        if kind == 2:  # NAME
            return self.new(spec)
        elemdesc, count = spec
        if int(elemdesc[0]) == 1 and elemdesc[1][0] in _BASE_DTYPES:
            return np.zeros(count if kind == 3 else 0, dtype=_BASE_DTYPES[elemdesc[1][0]])
        return [self._default(elemdesc) for _ in range(count if kind == 3 else 0)]


_RCLPY = RclpyTypes()


def rclpy_types() -> RclpyTypes:
    """The shared rclpy message-class provider."""
    return _RCLPY

"""Declared, validated configuration for core components.

A configurable component declares a frozen dataclass deriving from :class:`Config` whose fields
are made with :func:`setting` (default, description, unit, bounds, choices). Construction
validates every field and raises :class:`ConfigError` naming the field and the rule it broke, so
a bad value is refused where it enters, with a reason a user can act on.

Nodes turn the same declarations into ROS parameters with descriptors (ranges, descriptions), so
each parameter is declared in exactly one place. Nested configs flatten to dotted names
(``esc.dither_amplitude``).
"""
from __future__ import annotations

import array
import dataclasses
import math
import typing
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

__all__ = ['Config', 'ConfigError', 'Setting', 'setting']

_C = TypeVar('_C', bound='Config')


class ConfigError(ValueError):
    """A configuration value is invalid; the message names the setting and the rule."""


@dataclass(frozen=True)
class Setting:
    """Metadata of one leaf setting, as flattened by :meth:`Config.settings`."""

    name: str
    type: type
    default: Any
    description: str
    unit: str = ''
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple | None = None
    read_only: bool = False

    def check(self, value: Any) -> None:
        """Raise ConfigError unless ``value`` has this setting's type and lies within its bounds."""
        value = _coerce(self, value)
        if self.choices is not None and value not in self.choices:
            raise ConfigError(f'{self.name} = {value!r} is not one of {list(self.choices)}')
        values = value if isinstance(value, tuple) else (value,)
        for v in values:
            if isinstance(v, float) and not math.isfinite(v):
                raise ConfigError(f'{self.name} = {value!r} must be finite')
            if self.low is not None and (v < self.low or (self.low_open and v == self.low)):
                raise ConfigError(f'{self.name} = {value!r} must be {">" if self.low_open else ">="} {self.low}')
            if self.high is not None and (v > self.high or (self.high_open and v == self.high)):
                raise ConfigError(f'{self.name} = {value!r} must be {"<" if self.high_open else "<="} {self.high}')

    def bounds_text(self) -> str:
        """Human-readable range, e.g. ``(0, 1]``, for parameter descriptions."""
        if self.choices is not None:
            return 'one of ' + ', '.join(map(str, self.choices))
        if self.low is None and self.high is None:
            return ''
        lo = '-inf' if self.low is None else f'{self.low:g}'
        hi = 'inf' if self.high is None else f'{self.high:g}'
        opening = '(' if self.low_open or self.low is None else '['
        closing = ')' if self.high_open or self.high is None else ']'
        return f'{opening}{lo}, {hi}{closing}'


def setting(default: Any, description: str, *, unit: str = '', low: float | None = None,
            high: float | None = None, low_open: bool = False, high_open: bool = False,
            choices: tuple | None = None, read_only: bool = False) -> Any:
    """Declare a config field with its default, description and bounds.

    ``low``/``high`` are inclusive unless ``low_open``/``high_open``; ``choices`` restricts a
    string or number to a fixed set; ``read_only`` settings can only be given at start-up.
    """
    meta = dict(description=description, unit=unit, low=low, high=high, low_open=low_open,
                high_open=high_open, choices=choices, read_only=read_only)
    if isinstance(default, (list, tuple)):
        frozen = tuple(default)
        return dataclasses.field(default_factory=lambda: frozen, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _coerce(s: Setting, value: Any) -> Any:
    """Return ``value`` converted to the setting's type, or raise ConfigError."""
    t = s.type
    if t is bool:
        if isinstance(value, bool):
            return value
    elif t is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif t is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif t is str:
        if isinstance(value, str):
            return value
    elif t in (tuple, tuple[float, ...]):
        # Array parameters set at run time arrive from rclpy as array.array('d').
        if isinstance(value, array.array):
            value = value.tolist()
        if isinstance(value, (list, tuple)) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return tuple(float(v) for v in value)
    else:  # pragma: no cover - a declaration error, caught by the config tests
        raise TypeError(f'setting {s.name}: unsupported type {t!r}')
    raise ConfigError(f'{s.name} = {value!r} must be of type {getattr(t, "__name__", str(t))}')


def _leaf_type(annotation: Any) -> type:
    if annotation in (bool, int, float, str):
        return annotation
    if typing.get_origin(annotation) is tuple:
        return tuple[float, ...]
    return annotation


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints`` of a config class, once per class (it is slow, and a study builds
    configurations in every run)."""
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = typing.get_type_hints(cls)
    return hints


@dataclass(frozen=True)
class Config:
    """Base of all component configurations: validates in construction, flattens to settings."""

    def __post_init__(self) -> None:
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, Config):
                continue
            s = _setting_from_field(f, hints[f.name], f.name)
            if s is None:
                continue
            s.check(value)
            object.__setattr__(self, f.name, _coerce(s, value))
        # Every class's own rule, bases first: a config made of several (a node's settings mix
        # the component's, the input's and the pose's) keeps the rules of each.
        for cls in reversed(type(self).__mro__):
            rule = cls.__dict__.get('validate')
            if rule is not None:
                rule(self)

    def validate(self) -> None:
        """Cross-field checks; define in a subclass and raise ConfigError. Called after the field checks,
        for every class along the MRO that defines one (so an override need not call ``super()``)."""

    @classmethod
    def settings(cls, prefix: str = '') -> Iterator[Setting]:
        """Yield every leaf setting with its dotted name, defaults taken from the class."""
        hints = _hints(cls)
        for f in dataclasses.fields(cls):
            t = hints[f.name]
            if isinstance(t, type) and issubclass(t, Config):
                yield from t.settings(prefix + f.name + '.')
                continue
            s = _setting_from_field(f, t, prefix + f.name)
            if s is not None:
                yield s

    def flat(self, prefix: str = '') -> dict[str, Any]:
        """Return ``{dotted_name: value}`` for every leaf setting."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, Config):
                out.update(value.flat(prefix + f.name + '.'))
            elif f.metadata:
                out[prefix + f.name] = value
        return out

    @classmethod
    def from_flat(cls: type[_C], values: Mapping[str, Any], base: _C | None = None) -> _C:
        """Build a config from dotted names, starting from ``base`` (or the defaults).

        Unknown names raise ConfigError so that a typo in a parameter file is not ignored.
        """
        base = base if base is not None else cls()
        known = base.flat()
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ConfigError(f'unknown setting(s) {unknown} for {cls.__name__}')
        return base._with(dict(values), '')

    def _with(self: _C, values: dict[str, Any], prefix: str) -> _C:
        changes: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            name = prefix + f.name
            if isinstance(value, Config):
                sub = {k: v for k, v in values.items() if k.startswith(name + '.')}
                if sub:
                    changes[f.name] = value._with(sub, name + '.')
            elif name in values:
                changes[f.name] = values[name]
        if not changes:
            return self
        try:
            return dataclasses.replace(self, **changes)
        except ConfigError as exc:  # name nested settings by their dotted path, once
            text = str(exc)
            raise ConfigError(text if text.startswith(prefix) else f'{prefix}{text}') from None

    def replace(self: _C, **changes: Any) -> _C:
        """Copy with fields replaced (validated again)."""
        return dataclasses.replace(self, **changes)


def _setting_from_field(f: dataclasses.Field, annotation: Any, name: str) -> Setting | None:
    if not f.metadata:
        return None
    default = f.default if f.default is not dataclasses.MISSING else (
        f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
    m = f.metadata
    return Setting(name=name, type=_leaf_type(annotation), default=default,
                   description=m['description'], unit=m['unit'], low=m['low'], high=m['high'],
                   low_open=m['low_open'], high_open=m['high_open'], choices=m['choices'],
                   read_only=m['read_only'])

"""ROS parameters from core configs: one declaration per setting, validation in one place.

:class:`ConfigParameters` declares every leaf setting of a :class:`~sonar_tracking.core.config.Config`
as a ROS parameter whose descriptor carries the description, unit and range, so ``ros2 param
describe`` tells users what a value means. Start-up overrides that break a rule are reported in
the log and replaced by the default; runtime changes (``ros2 param set``) are refused with the
rule as the reason, and accepted changes reach the node through ``on_change``.

Every parameter keeps its declared type: an integer given for a double (``ros2 param set ... 5``,
YAML ``1``) or an integer array for a double array is converted, anything else of another type is
refused. Start-up-only settings are ``read_only`` in their descriptors; their start-up values are
checked before they are declared, so a bad one is replaced by the default without a later set.
"""
from __future__ import annotations

import array
import sys
from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from sonar_tracking.core.config import Config, ConfigError, Setting

__all__ = ['ConfigParameters', 'descriptor_for', 'start_value', 'declare_choice', 'unknown_overrides',
           'warn_unknown_overrides']

_TYPES = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
          float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}
_INT_MAX = 2**63 - 1


def descriptor_for(s: Setting, read_only: bool | None = None) -> ParameterDescriptor:
    """The ROS descriptor of a setting: description with unit and range, numeric range constraint."""
    read_only = s.read_only if read_only is None else read_only
    text = s.description + (f' [{s.unit}]' if s.unit else '')
    bounds = s.bounds_text()
    d = ParameterDescriptor(name=s.name, description=text, read_only=read_only,
                            additional_constraints=(bounds + ('; ' if bounds else '') +
                                                    ('start-up only' if read_only else '')).strip('; '),
                            type=_TYPES.get(s.type, ParameterType.PARAMETER_DOUBLE_ARRAY))
    if s.type is float and (s.low is not None or s.high is not None):
        d.floating_point_range = [FloatingPointRange(
            from_value=-sys.float_info.max if s.low is None else float(s.low),
            to_value=sys.float_info.max if s.high is None else float(s.high), step=0.0)]
    elif s.type is int and (s.low is not None or s.high is not None):
        d.integer_range = [IntegerRange(from_value=-_INT_MAX if s.low is None else int(s.low),
                                        to_value=_INT_MAX if s.high is None else int(s.high), step=0)]
    return d


def _to_declared_type(s: Setting, value: Any) -> Any:
    """``value`` with integers made doubles where ``s`` is a double or double array; else unchanged."""
    if s.type is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if s.type not in _TYPES and isinstance(value, (list, tuple, array.array)) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return [float(v) for v in value]
    return value


def start_value(node: Node, s: Setting, default: Any) -> Any:
    """The start-up value of setting ``s``: its override (``-p``, a parameter file) if valid, else
    ``default``, with the reason in the log."""
    overrides = _overrides(node)
    if s.name not in overrides:
        return default
    given = _to_declared_type(s, overrides[s.name].value)
    try:
        s.check(given)
    except ConfigError as exc:
        node.get_logger().error(f'parameter {exc}; using {default!r}')
        return default
    return _ros_value(given)


def _overrides(node: Node) -> dict[str, Parameter]:
    """The start-up values given to ``node`` (``-p``, its parameter files' sections)."""
    return getattr(node, '_parameter_overrides', {})  # rclpy has no public accessor for these


def unknown_overrides(node: Node) -> list[str]:
    """Names given to ``node`` at start-up (``-p``, the sections of its parameter files that apply to
    it) that it has not declared: a misspelt name, or one of another node."""
    return sorted(n for n in _overrides(node) if not node.has_parameter(n) and not n.startswith('qos_overrides.'))


def warn_unknown_overrides(node: Node) -> None:
    """Log the start-up names ``node`` does not know (:func:`unknown_overrides`), once."""
    unknown = unknown_overrides(node)
    if unknown:
        node.get_logger().warning(f'unknown parameter(s) for {node.get_fully_qualified_name()}, ignored: '
                                  f'{", ".join(unknown)} (misspelt, or meant for another node? '
                                  f'`ros2 param list {node.get_fully_qualified_name()}` lists its names)')


def declare_choice(node: Node, s: Setting, default: str, choices: tuple[str, ...]) -> str:
    """Declare setting ``s`` read before the others because it decides their defaults (a scenario, a
    preset): its start-up value if it is one of ``choices``, else ``default`` with the reason logged."""
    value = start_value(node, s, default)
    if value not in choices:
        node.get_logger().error(f'parameter {s.name}: {value!r} is not one of {list(choices)}; using {default!r}')
        value = default
    return node.declare_parameter(s.name, value, descriptor_for(s), ignore_override=True).value


class ConfigParameters:
    """Declares ``base``'s settings on ``node`` and keeps :attr:`config` in step with the parameters."""

    def __init__(self, node: Node, base: Config, on_change: Callable[[Config, Config], None] | None = None,
                 skip: tuple[str, ...] = (), mutable: set[str] | None = None,
                 check: Callable[[Config], None] | None = None) -> None:
        """``skip``: settings the node declared itself already (read first to choose ``base``).
        ``mutable``: the settings that may change while running (default: those not ``read_only``).
        ``check``: a further test of a whole config (raising ConfigError), for rules that need
        more than the config itself (a table file that must exist, say).
        """
        self.node = node
        self.on_change = on_change
        self.check = check
        self.settings = {s.name: s for s in type(base).settings()}
        self.read_only = {n for n, s in self.settings.items() if (n not in mutable if mutable is not None
                                                                   else s.read_only)}
        defaults = {n: _ros_value(v) for n, v in base.flat().items()}
        values = {n: (node.get_parameter(n).value if n in skip else start_value(node, s, defaults[n]))
                  for n, s in self.settings.items()}
        try:
            self.config = type(base).from_flat(values, base=base)
            if check is not None:
                check(self.config)
        except ConfigError as exc:
            node.get_logger().error(f'parameters are inconsistent ({exc}); using the defaults')
            values = {n: (values[n] if n in skip else defaults[n]) for n in self.settings}
            self.config = base
        for name, s in self.settings.items():
            if name not in skip:
                node.declare_parameter(name, values[name], descriptor_for(s, name in self.read_only),
                                       ignore_override=True)
        node.add_pre_set_parameters_callback(self._pre_set)
        node.add_on_set_parameters_callback(self._on_set)
        warn_unknown_overrides(node)

    def _pre_set(self, params: list[Parameter]) -> list[Parameter]:
        out = []
        for p in params:
            s = self.settings.get(p.name)
            value = _to_declared_type(s, p.value) if s is not None else p.value
            out.append(p if value is p.value else Parameter(p.name, value=value))
        return out

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in params if p.name in self.settings}
        if not changes:
            return SetParametersResult(successful=True)
        try:
            new = type(self.config).from_flat(changes, base=self.config)
            if self.check is not None:
                self.check(new)
        except ConfigError as exc:
            # The reason starts with what was set: a rule between settings may name another one first.
            given = ', '.join(f'{n} = {v!r}' for n, v in changes.items())
            text = str(exc)
            reason = text if text.startswith(given) else f'{given} refused: {text}'
            return SetParametersResult(successful=False, reason=reason)
        old, self.config = self.config, new
        if self.on_change is not None and new != old:
            self.on_change(old, new)
        return SetParametersResult(successful=True)


def _ros_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value

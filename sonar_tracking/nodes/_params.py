"""ROS parameters from core configs: one declaration per setting, validation in one place.

:class:`ConfigParameters` declares every leaf setting of a :class:`~sonar_tracking.core.config.Config`
as a ROS parameter whose descriptor carries the description, unit and range, so ``ros2 param
describe`` tells users what a value means. Start-up overrides that break a rule are reported in
the log and replaced by the default; runtime changes (``ros2 param set``) are refused with the
rule as the reason, and accepted changes reach the node through ``on_change``.

Settings marked ``read_only`` can only be given at start-up. They are enforced here rather than
by the descriptor's ``read_only`` flag so that a bad start-up value can still be put back to its
default.
"""
from __future__ import annotations

import sys
from typing import Any, Callable

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from sonar_tracking.core.config import Config, ConfigError, Setting

__all__ = ['ConfigParameters', 'descriptor_for']

_TYPES = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
          float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}
_INT_MAX = 2**63 - 1


def descriptor_for(s: Setting, read_only: bool | None = None) -> ParameterDescriptor:
    """The ROS descriptor of a setting: description with unit and range, numeric range constraint."""
    read_only = s.read_only if read_only is None else read_only
    text = s.description + (f' [{s.unit}]' if s.unit else '')
    bounds = s.bounds_text()
    d = ParameterDescriptor(name=s.name, description=text,
                            additional_constraints=(bounds + ('; ' if bounds else '') +
                                                    ('start-up only' if read_only else '')).strip('; '),
                            type=_TYPES.get(s.type, ParameterType.PARAMETER_DOUBLE_ARRAY))
    if s.type is float:
        # Integer values are accepted for doubles (YAML "1" for 1.0) and converted by the config.
        d.dynamic_typing = True
        if s.low is not None or s.high is not None:
            d.floating_point_range = [FloatingPointRange(
                from_value=-sys.float_info.max if s.low is None else float(s.low),
                to_value=sys.float_info.max if s.high is None else float(s.high), step=0.0)]
    elif s.type is int and (s.low is not None or s.high is not None):
        d.integer_range = [IntegerRange(from_value=-_INT_MAX if s.low is None else int(s.low),
                                        to_value=_INT_MAX if s.high is None else int(s.high), step=0)]
    return d


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
        defaults = base.flat()
        log = node.get_logger()
        values: dict[str, Any] = {}
        for name, s in self.settings.items():
            default = _ros_value(defaults[name])
            if name in skip:
                values[name] = node.get_parameter(name).value
                continue
            try:
                param = node.declare_parameter(name, default, descriptor_for(s, name in self.read_only))
            except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
                log.error(f'parameter {name}: start-up value refused ({exc}); using {default!r}')
                param = node.declare_parameter(name, default, descriptor_for(s, name in self.read_only),
                                               ignore_override=True)
            value = param.value
            try:
                s.check(value)
            except ConfigError as exc:
                log.error(f'parameter {name}: {exc}; using {default!r}')
                node.set_parameters([Parameter(name, value=default)])
                value = default
            values[name] = value
        try:
            self.config = type(base).from_flat(values, base=base)
            if check is not None:
                check(self.config)
        except ConfigError as exc:
            log.error(f'parameters are inconsistent ({exc}); using the defaults')
            node.set_parameters([Parameter(n, value=_ros_value(v)) for n, v in defaults.items() if n not in skip])
            self.config = base
        node.add_on_set_parameters_callback(self._on_set)

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p.value for p in params if p.name in self.settings}
        if not changes:
            return SetParametersResult(successful=True)
        current = self.config.flat()
        for name, value in changes.items():
            if name in self.read_only and value != _ros_value(current[name]):
                return SetParametersResult(successful=False, reason=(
                    f'{name} can only be set at start-up: restart the node with -p {name}:={value}'))
        try:
            new = type(self.config).from_flat(changes, base=self.config)
            if self.check is not None:
                self.check(new)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        old, self.config = self.config, new
        if self.on_change is not None and new != old:
            self.on_change(old, new)
        return SetParametersResult(successful=True)


def _ros_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value

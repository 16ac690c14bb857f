"""ROS 2 parameter files read the way rcl reads them, for tools that apply one without starting a node.

A parameter file maps node-name patterns to ``ros__parameters:`` sections. A node takes every section
whose pattern matches its fully qualified name, in file order, a later value replacing an earlier one
(what rclpy does with ``--params-file``). Patterns: ``/ns/node`` (exact), ``node`` (the same as
``/node``: root namespace only), ``*`` (one name), ``**`` (any number of names, none included), so
``/**/node`` is the node in any namespace and ``/**`` every node. Nested mappings
(``ns: {node: {ros__parameters: ...}}``) spell ``/ns/node``.

The package's files key each section ``/**/NODE_NAME:`` so they apply under any namespace
(``-r __ns:=/auv1``); a section keyed by a bare node name applies in the root namespace only.
"""
from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = ['ParamFileError', 'load', 'sections', 'matches', 'parameters_for', 'flatten', 'root_only_sections']

PARAMS_KEY = 'ros__parameters'


class ParamFileError(ValueError):
    """A parameter file that cannot be read or is not a mapping of node sections."""


def load(path: str | Path) -> dict:
    """The YAML mapping of a parameter file; ParamFileError with the reason if it is unusable."""
    import yaml
    try:
        data = yaml.safe_load(Path(path).read_bytes().decode('utf-8'))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ParamFileError(f'cannot read parameters from {path}: {exc}') from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ParamFileError(f'{path}: expected a mapping of node sections, got {type(data).__name__}')
    return data


def sections(data: dict, prefix: str = '') -> Iterator[tuple[str, dict]]:
    """``(pattern, parameters)`` of each node section in file order; patterns start with ``/``."""
    for key, value in data.items():
        if not isinstance(value, dict):
            continue
        name = prefix + '/' + str(key).strip('/')
        if PARAMS_KEY in value:
            yield name, value[PARAMS_KEY] or {}
        else:
            yield from sections(value, name)


def _pattern(pattern: str) -> re.Pattern[str]:
    parts = []
    for token in pattern.strip('/').split('/'):
        if token == '**':
            parts.append('(/[^/]+)*')
        else:
            parts.append('/' + '[^/]+'.join(re.escape(t) for t in token.split('*')))
    return re.compile(''.join(parts) + '$')


def matches(pattern: str, fqn: str) -> bool:
    """Whether section ``pattern`` applies to the node of fully qualified name ``fqn``."""
    return _pattern(pattern).match(fqn) is not None


def fqn(node: str, namespace: str = '/') -> str:
    """The fully qualified name of ``node`` in ``namespace``."""
    return namespace.rstrip('/') + '/' + node


def flatten(params: dict, prefix: str = '') -> dict[str, Any]:
    """Nested parameter mappings as ROS names: ``{a: {b: 1}}`` is ``{'a.b': 1}``."""
    out: dict[str, Any] = {}
    for key, value in params.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(flatten(value, name + '.'))
        else:
            out[name] = value
    return out


def parameters_for(data: dict, node: str, namespace: str = '/') -> dict[str, Any] | None:
    """The flat parameters ``node`` in ``namespace`` takes from the file (sections merged in file
    order); None when no section applies."""
    name = fqn(node, namespace)
    found = [flatten(p) for pattern, p in sections(data) if matches(pattern, name)]
    if not found:
        return None
    merged: dict[str, Any] = {}
    for p in found:
        merged.update(p)
    return merged


def root_only_sections(data: dict, node: str) -> list[str]:
    """Sections meant for ``node`` that apply in the root namespace only (keyed ``node`` or
    ``/node``): run elsewhere, the node would silently not get them."""
    return [pattern for pattern, _ in sections(data) if matches(pattern, '/' + node)
            and not matches(pattern, fqn(node, '/some/namespace'))]

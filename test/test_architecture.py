"""The package's layers import only downwards, and no modules import each other in a cycle.

The folders of ``sonar_tracking`` are layers (DESIGN §2, ``docs/architecture.md``). Each may import
the layers :data:`DIRECT` names for it and everything below those; ``process`` and ``resources``
are importable from every layer and import only the standard library. Every import statement
counts: absolute and relative, at any depth, inside functions, and under ``if TYPE_CHECKING``.

Run ``python test/test_architecture.py`` for the list of violations of the working tree.
"""
from __future__ import annotations

import ast
import shutil
import sys
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'sonar_tracking'

#: The layers each layer names; it may also import whatever those may import.
DIRECT: dict[str, set[str]] = {
    'cli': {'nodes', 'studies'},
    'nodes': {'ros', 'sim'},
    'ros': {'io'},
    'io': {'msgs'},
    'studies': {'sim', 'io', 'msgs'},
    'sim': {'core'},
    'msgs': {'core'},
    'core': set(),
}
#: Standard-library-only modules that every layer may import.
SHARED = {'process', 'resources'}


def allowed_layers(layer: str) -> set[str]:
    """``layer`` itself and every layer below it by :data:`DIRECT`."""
    out, todo = {layer}, [layer]
    while todo:
        for lower in DIRECT[todo.pop()]:
            if lower not in out:
                out.add(lower)
                todo.append(lower)
    return out


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted name -> file of every module of the package under ``root``."""
    out = {}
    for path in sorted((root / PACKAGE).rglob('*.py')):
        parts = list(path.relative_to(root).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts = parts[:-1]
        out['.'.join(parts)] = path
    return out


def imports(module: str, path: Path, known: Iterable[str]) -> list[tuple[int, str]]:
    """``(line, module)`` for every import of one of ``known`` modules in ``path``; ``from X import a``
    counts as ``X.a`` when that is a module, else as ``X``; a name inside a module counts as the module."""
    known = set(known)
    here = module.split('.') if path.name == '__init__.py' else module.split('.')[:-1]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[:len(here) - (node.level - 1)] if node.level > 1 else list(here)
                target = '.'.join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ''
            targets = [f'{target}.{a.name}' if f'{target}.{a.name}' in known else target for a in node.names]
        else:
            continue
        for name in targets:
            while name and name not in known:
                name = name.rpartition('.')[0]
            if name:
                found.append((node.lineno, name))
    return found


def layer_of(module: str) -> str:
    """The layer (top folder or shared module) of a module; '' for the package's own ``__init__``."""
    parts = module.split('.')
    return parts[1] if len(parts) > 1 else ''


def direction_violations(root: Path = ROOT) -> list[str]:
    """Imports against :data:`DIRECT`, imports by the shared modules, and modules outside any layer."""
    mods = modules(root)
    bad = []
    for module, path in mods.items():
        layer = layer_of(module)
        where = path.relative_to(root).as_posix()
        if layer and layer not in DIRECT and layer not in SHARED:
            bad.append(f'{where}: {layer} is no declared layer (add it to DIRECT and docs/architecture.md)')
            continue
        for line, target in imports(module, path, mods):
            other = layer_of(target)
            if layer in SHARED or layer == '':
                if target != module:
                    bad.append(f'{where}:{line} imports {target} (this module may import the standard library only)')
            elif other in SHARED or other == layer:
                continue
            elif other not in allowed_layers(layer):
                bad.append(f'{where}:{line} imports {target}: {layer} may not import {other}')
    for name in SHARED:
        path = root / PACKAGE / f'{name}.py'
        for node in ast.walk(ast.parse(path.read_text())):
            tops = ([a.name for a in node.names] if isinstance(node, ast.Import)
                    else [node.module or ''] if isinstance(node, ast.ImportFrom) and not node.level else [])
            for top in (t.split('.')[0] for t in tops):
                if top not in sys.stdlib_module_names and top != '__future__':
                    where = path.relative_to(root).as_posix()
                    bad.append(f'{where}:{node.lineno} imports {top}, not in the standard library')
    return bad


def cycles(root: Path = ROOT) -> list[list[str]]:
    """Groups of modules that import each other, directly or around a loop (Tarjan's strongly
    connected components of the import graph); a module importing itself is a group of one."""
    mods = modules(root)
    graph = {m: sorted({t for _, t in imports(m, p, mods)}) for m, p in mods.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(graph[start]))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, edges = work[-1]
            for nxt in edges:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(graph[nxt])))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        group.append(m)
                        if m == node:
                            break
                    if len(group) > 1 or node in graph[node]:
                        found.append(sorted(group))
    return found


def test_every_import_follows_the_declared_direction():
    assert direction_violations() == []


def test_no_modules_import_each_other_in_a_cycle():
    assert cycles() == []


def test_the_direction_is_a_hierarchy():
    """No layer reaches itself through the layers it names (the declaration itself has no cycle)."""
    for layer, names in DIRECT.items():
        assert all(layer not in allowed_layers(lower) for lower in names), layer


@pytest.fixture
def copy_of_package(tmp_path):
    shutil.copytree(ROOT / PACKAGE, tmp_path / PACKAGE, ignore=shutil.ignore_patterns('__pycache__', '*.nb?'))
    return tmp_path


def append(root: Path, relative: str, text: str) -> None:
    path = root / PACKAGE / relative
    path.write_text(path.read_text() + text)


def test_an_upward_import_in_a_copy_is_caught(copy_of_package):
    append(copy_of_package, 'core/records.py', '\ndef f():\n    from ..cli import demo\n')
    append(copy_of_package, 'studies/metrics.py', '\nfrom sonar_tracking.ros.qos import input_profile\n')
    append(copy_of_package, 'process.py', '\nimport numpy\n')
    bad = direction_violations(copy_of_package)
    assert any(b.startswith('sonar_tracking/core/records.py:') and 'core may not import cli' in b for b in bad), bad
    assert any(b.startswith('sonar_tracking/studies/metrics.py:') and 'studies may not import ros' in b
               for b in bad), bad
    assert any('process.py' in b and 'numpy, not in the standard library' in b for b in bad), bad
    assert len(bad) == 3, bad


def test_a_type_only_cycle_in_a_copy_is_caught(copy_of_package):
    """``records`` and ``sector`` of core importing each other, one of them only for type hints."""
    append(copy_of_package, 'core/records.py', '\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n'
                                               '    from sonar_tracking.core.sector import SectorGeometry\n')
    append(copy_of_package, 'core/sector.py', '\nfrom .records import DETECTION_DTYPE\n')
    assert direction_violations(copy_of_package) == []
    assert ['sonar_tracking.core.records', 'sonar_tracking.core.sector'] in cycles(copy_of_package)


def test_a_new_top_folder_must_be_declared(copy_of_package):
    (copy_of_package / PACKAGE / 'extras').mkdir()
    (copy_of_package / PACKAGE / 'extras' / '__init__.py').write_text('')
    assert direction_violations(copy_of_package) == [
        'sonar_tracking/extras/__init__.py: extras is no declared layer (add it to DIRECT and docs/architecture.md)']


@pytest.mark.parametrize('source, module, is_package, found', [
    ('from ..sim import Simulator', 'sonar_tracking.core.fls.x', False, 'sonar_tracking.core.sim'),
    ('from .. import studies', 'sonar_tracking.nodes.x', False, 'sonar_tracking.studies'),
    ('from ..studies.metrics import gospa', 'sonar_tracking.nodes.x', False, 'sonar_tracking.studies.metrics'),
    ('from .reader import read_bag', 'sonar_tracking.io.bags', True, 'sonar_tracking.io.bags.reader'),
    ('def f():\n    import sonar_tracking.sim.scene', 'sonar_tracking.msgs.y', False, 'sonar_tracking.sim.scene'),
    ('from sonar_tracking import sim as s', 'sonar_tracking.ros.z', False, 'sonar_tracking.sim'),
])
def test_the_checker_resolves_relative_nested_and_package_imports(tmp_path, source, module, is_package, found):
    # In a package's __init__ (is_package) one dot is the package itself, as Python resolves it.
    path = tmp_path / ('__init__.py' if is_package else 'x.py')
    path.write_text(source)
    known = {found, found.rpartition('.')[0]}
    assert [t for _, t in imports(module, path, known)] == [found]


if __name__ == '__main__':
    problems = direction_violations() + ['cycle: ' + ' -> '.join(c) for c in cycles()]
    print('\n'.join(problems) or 'imports follow the declared direction; no cycles')
    sys.exit(1 if problems else 0)

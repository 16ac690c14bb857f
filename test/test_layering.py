"""Layering: the runtime packages never import the simulator (``core.sim``) or the studies (``core.eval``).

Every import statement of every module is parsed with ``ast`` (absolute and relative imports, at
any depth, including imports inside functions) and resolved to an absolute module name.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Packages that run on the vehicle (folder, dotted name).
RUNTIME = [('sonar_tracking/core/detection', 'sonar_tracking.core.detection'),
           ('sonar_tracking/core/tracking', 'sonar_tracking.core.tracking'),
           ('sonar_tracking/core/fls', 'sonar_tracking.core.fls'),
           ('sonar_tracking/core/gpf', 'sonar_tracking.core.gpf'),
           ('sonar_tracking/nodes', 'sonar_tracking.nodes'),
           ('sonar_tracking/ros', 'sonar_tracking.ros'),
           ('msg_adapters', 'msg_adapters')]
FORBIDDEN = ('sonar_tracking.core.sim', 'sonar_tracking.core.eval')
#: The one node that IS the simulator (it publishes the simulated sonar) may import core.sim.
ALLOWED = {'sonar_tracking/nodes/seaking_sim.py': ('sonar_tracking.core.sim',)}


def module_name(path: Path, package_dir: Path, package: str) -> str:
    parts = list(path.relative_to(package_dir).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts = parts[:-1]
    return '.'.join([package, *parts])


def imported_modules(source: str, module: str, is_package: bool) -> list[tuple[int, str]]:
    """``(line, absolute module name)`` of every import in ``source``; for ``from X import a`` both
    ``X`` and ``X.a`` (``a`` may be a submodule)."""
    here = module.split('.') if is_package else module.split('.')[:-1]
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[:len(here) - (node.level - 1)] if node.level > 1 else list(here)
                target = '.'.join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ''
            out.append((node.lineno, target))
            out += [(node.lineno, f'{target}.{alias.name}') for alias in node.names]
    return out


def forbidden_imports(package_dir: Path, package: str, root: Path = ROOT) -> list[str]:
    bad = []
    for path in sorted(package_dir.rglob('*.py')):
        module = module_name(path, package_dir, package)
        allowed = ALLOWED.get(path.relative_to(root).as_posix(), ())
        for line, name in imported_modules(path.read_text(), module, path.name == '__init__.py'):
            if any((name == f or name.startswith(f + '.')) and f not in allowed for f in FORBIDDEN):
                bad.append(f'{path.relative_to(root)}:{line} imports {name}')
    return bad


@pytest.mark.parametrize('folder, package', RUNTIME, ids=[p for _, p in RUNTIME])
def test_runtime_package_imports_neither_sim_nor_eval(folder, package):
    package_dir = ROOT / folder
    assert package_dir.is_dir(), f'{folder} is gone: update RUNTIME in this test'
    assert forbidden_imports(package_dir, package) == []


def test_the_simulator_node_is_the_only_exception_and_still_may_not_import_eval(tmp_path):
    nodes = tmp_path / 'sonar_tracking' / 'nodes'
    nodes.mkdir(parents=True)
    (nodes / 'other.py').write_text('from ..core.sim import Simulator\n')
    (nodes / 'seaking_sim.py').write_text('from ..core.eval import metrics\n')
    bad = forbidden_imports(nodes, 'sonar_tracking.nodes', tmp_path)
    assert bad == ['sonar_tracking/nodes/other.py:1 imports sonar_tracking.core.sim',
                   'sonar_tracking/nodes/other.py:1 imports sonar_tracking.core.sim.Simulator',
                   'sonar_tracking/nodes/seaking_sim.py:1 imports sonar_tracking.core.eval',
                   'sonar_tracking/nodes/seaking_sim.py:1 imports sonar_tracking.core.eval.metrics']


@pytest.mark.parametrize('source, module, is_package, found', [
    ('from ..sim import Simulator', 'sonar_tracking.core.fls.x', False, 'sonar_tracking.core.sim'),
    ('from .. import eval', 'sonar_tracking.core.fls.x', False, 'sonar_tracking.core.eval'),
    ('from ..core.eval.metrics import gospa', 'sonar_tracking.nodes.x', False, 'sonar_tracking.core.eval.metrics'),
    ('from ..eval import fls_frames', 'sonar_tracking.core.gpf', True, 'sonar_tracking.core.eval.fls_frames'),
    ('from .eval import x', 'sonar_tracking.core.gpf', True, None),
    ('def f():\n    import sonar_tracking.core.sim.scene', 'msg_adapters.y', False, 'sonar_tracking.core.sim.scene'),
    ('from sonar_tracking.core import sim as s', 'sonar_tracking.ros.z', False, 'sonar_tracking.core.sim'),
    ('from .simulation import x', 'sonar_tracking.core.fls.y', False, None),
])
def test_the_checker_resolves_relative_and_nested_imports(source, module, is_package, found):
    # In a package's __init__ (is_package) one dot is the package itself, as Python resolves it.
    names = [n for _, n in imported_modules(source, module, is_package)]
    hits = [n for n in names if any(n == f or n.startswith(f + '.') for f in FORBIDDEN)]
    if found is None:
        assert hits == []
    else:
        assert found in hits, names

"""Writing the results of the ``sonar_eval`` studies: JSON, plots and tables, each path announced."""
from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ['write_json', 'write_plot', 'table_command', 'seed_split_or_none', 'comma_choices']


def write_json(path: Path, data: Any, allow_nan: bool = True) -> None:
    """``data`` as indented JSON at ``path`` (parent folders made); prints ``wrote PATH``.
    ``allow_nan=False`` refuses NaN and infinity, which strict JSON readers reject."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, allow_nan=allow_nan) + '\n')
    print(f'wrote {path}')


def write_plot(path: Path, draw: Callable[[Any, Path], None], result: Any) -> None:
    """``draw(result, path)``; prints ``wrote PATH``."""
    draw(result, path)
    print(f'wrote {path}')


def table_command(name: str, args: Any, run: Callable[[Any], dict], format_table: Callable[[dict], str]) -> int:
    """A README-table study: ``run(pool)`` on the pool of ``--jobs`` / ``--cluster``, then the wall
    time, the table, and ``--json``; returns the exit status (2 when the cluster is unreachable)."""
    from sonar_tracking.studies.montecarlo import ClusterUnavailable, pool_from_args
    t0 = time.monotonic()
    try:
        with pool_from_args(args) as pool:
            result = run(pool)
            where = pool.describe()
    except ClusterUnavailable as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    result['wall_s'] = time.monotonic() - t0
    print(f'{name}: {result["wall_s"]:.0f} s on {where}')
    print(format_table(result))
    if args.json:
        write_json(args.json, result)
    return 0


def seed_split_or_none(args: Any, tuned_on) -> Any:
    """The study's :class:`~sonar_tracking.studies.evidence.SeedSplit` from ``--calibration-seeds`` and
    ``--seeds``, or None after printing why the seeds are refused (the caller exits with 2)."""
    from sonar_tracking.studies.evidence import SeedError, seed_split_from_args
    try:
        return seed_split_from_args(args, tuned_on=tuned_on)
    except SeedError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return None


def comma_choices(text: str, known, option: str) -> list[str] | None:
    """The items of a comma list ``text`` if each is one of ``known`` and none repeats; else None after
    printing why (the caller exits with 2)."""
    items = [c.strip() for c in text.split(',') if c.strip()]
    bad = [c for c in items if c not in known]
    if bad or not items or len(set(items)) != len(items):
        print(f'error: {option}: unknown or repeated {bad or items}; choose from {",".join(known)}', file=sys.stderr)
        return None
    return items

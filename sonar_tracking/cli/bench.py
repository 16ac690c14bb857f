"""Benchmark harness behind ``sonar_eval bench``.

A case builds its inputs once and returns the zero-argument function to time. Each repeat calls
it ``number`` times (chosen so a repeat lasts at least ``min_time``) with the garbage collector
off, as :mod:`timeit` does; the table reports the median time per call and its spread (25th to
75th percentile) over repeats. A case may name another as ``compare_to``: its ratio is the other
case's median divided by its own, taken in the same run. ``limit_s`` is the target an issue set;
the table says whether the median meets it. A ``self_timed`` case returns the seconds it measured
itself (for work that spans processes, such as a node's throughput; a sequence of seconds counts
as that many samples, such as message latencies), and ``derived`` turns the
result into further figures shown beside it (such as "x real time"). Timing lives here and never
in tests.
"""
from __future__ import annotations

import fnmatch
import gc
import importlib
import os
import pkgutil
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.cli._output import write_json

__all__ = ['Case', 'Result', 'register', 'cases', 'run_case', 'run', 'format_table', 'main_args']


@dataclass(frozen=True)
class Case:
    """One benchmark: ``make()`` builds inputs and returns the function to time."""

    name: str
    group: str
    make: Callable[[], Callable[[], Any]]
    description: str = ''
    compare_to: str | None = None
    limit_s: float | None = None
    repeats: int = 30
    min_time: float = 0.002
    self_timed: bool = False
    derived: Callable[[Result], dict] | None = None


@dataclass
class Result:
    """Timing of one case: seconds per call over repeats."""

    name: str
    group: str
    description: str
    median_s: float
    p25_s: float
    p75_s: float
    min_s: float
    max_s: float
    repeats: int
    number: int
    compare_to: str | None = None
    ratio: float | None = None
    limit_s: float | None = None
    meets_limit: bool | None = None
    extra: dict = field(default_factory=dict)


_CASES: dict[str, Case] = {}


def register(case: Case) -> Case:
    """Add a case to the registry (names must be unique)."""
    if case.name in _CASES and _CASES[case.name] is not case:
        raise ValueError(f'benchmark case {case.name!r} registered twice')
    _CASES[case.name] = case
    return case


def cases() -> dict[str, Case]:
    """All registered cases, importing every module of ``sonar_tracking.cli.bench_cases``."""
    from sonar_tracking.cli import bench_cases
    for mod in pkgutil.iter_modules(bench_cases.__path__):
        importlib.import_module(f'{bench_cases.__name__}.{mod.name}')
    return dict(_CASES)


def run_case(case: Case, repeats: int | None = None) -> Result:
    """Time one case."""
    fn = case.make()
    if case.self_timed:
        samples: list[float] = []
        for _ in range(repeats or case.repeats):
            got = fn()
            samples.extend(np.atleast_1d(np.asarray(got, dtype=float)).tolist())
        return _result(case, np.asarray(samples), 1)
    fn()  # warm-up: imports, caches, first-call allocation
    number = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        if time.perf_counter() - t0 >= case.min_time or number >= 1 << 20:
            break
        number *= 2
    times = []
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(repeats or case.repeats):
            t0 = time.perf_counter()
            for _ in range(number):
                fn()
            times.append((time.perf_counter() - t0) / number)
    finally:
        if enabled:
            gc.enable()
    return _result(case, np.asarray(times), number)


def _result(case: Case, t: np.ndarray, number: int) -> Result:
    med = float(np.median(t))
    r = Result(name=case.name, group=case.group, description=case.description, median_s=med,
               p25_s=float(np.percentile(t, 25)), p75_s=float(np.percentile(t, 75)),
               min_s=float(t.min()), max_s=float(t.max()), repeats=len(t), number=number,
               compare_to=case.compare_to, limit_s=case.limit_s,
               meets_limit=None if case.limit_s is None else med <= case.limit_s)
    if case.derived is not None:
        r.extra = case.derived(r)
    return r


def run(patterns: list[str] | None = None, repeats: int | None = None,
        progress: Callable[[str], None] | None = None) -> list[Result]:
    """Run the cases whose name matches any glob in ``patterns`` (all if none), plus their baselines."""
    all_cases = cases()
    chosen = [c for c in all_cases.values()
              if not patterns or any(fnmatch.fnmatch(c.name, p) or p in c.name for p in patterns)]
    names = {c.name for c in chosen}
    for c in chosen:           # grows while it runs: a baseline's own baseline comes along too
        if c.compare_to and c.compare_to not in names:
            chosen.append(all_cases[c.compare_to])
            names.add(c.compare_to)
    results: dict[str, Result] = {}
    for c in chosen:
        if progress:
            progress(c.name)
        results[c.name] = run_case(c, repeats)
    for r in results.values():
        if r.compare_to:
            r.ratio = results[r.compare_to].median_s / r.median_s
    return list(results.values())


def _fmt_time(s: float) -> str:
    if s >= 1.0:
        return f'{s:.3g} s'
    if s >= 1e-3:
        return f'{s * 1e3:.3g} ms'
    return f'{s * 1e6:.3g} us'


def format_table(results: list[Result]) -> str:
    """Plain-text table: case, median, spread (p25-p75), repeats x calls, ratio, limit."""
    rows = [('case', 'median', 'p25 .. p75', 'runs', 'ratio', 'limit', 'note')]
    for r in results:
        ratio = f'{r.ratio:.1f}x vs {r.compare_to}' if r.ratio is not None else ''
        limit = '' if r.limit_s is None else f'{"ok" if r.meets_limit else "OVER"} < {_fmt_time(r.limit_s)}'
        note = ', '.join(f'{k} {v:.3g}' if isinstance(v, float) else f'{k} {v}' for k, v in r.extra.items())
        rows.append((r.name, _fmt_time(r.median_s), f'{_fmt_time(r.p25_s)} .. {_fmt_time(r.p75_s)}',
                     f'{r.repeats}x{r.number}', ratio, limit, note))
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = ['  '.join(v.ljust(w) for v, w in zip(row, widths)).rstrip() for row in rows]
    lines.insert(1, '  '.join('-' * w for w in widths))
    return '\n'.join(lines)


def machine_info() -> dict[str, Any]:
    """Where the numbers were taken."""
    return {'python': sys.version.split()[0], 'numpy': np.__version__, 'platform': platform.platform(),
            'processor': platform.processor() or platform.machine(), 'cpus': os.cpu_count(),
            'time': time.strftime('%Y-%m-%dT%H:%M:%S%z')}


def add_arguments(parser: Any) -> None:
    """Arguments of ``sonar_eval bench``."""
    parser.add_argument('patterns', nargs='*', help='run only cases whose name matches (glob or substring)')
    parser.add_argument('--repeats', type=int, default=None, help='repeats per case (default: per case)')
    parser.add_argument('--json', type=Path, default=None, help='also write the results to this JSON file')
    parser.add_argument('--list', action='store_true', help='list the cases and exit')


def main_args(args: Any) -> int:
    """Run ``sonar_eval bench`` with parsed arguments; returns the exit status."""
    if args.list:
        for c in cases().values():
            print(f'{c.name:40s} {c.description}')
        return 0
    if args.repeats is not None and args.repeats < 1:
        print('error: --repeats must be >= 1', file=sys.stderr)
        return 2
    results = run(args.patterns, args.repeats, progress=lambda n: print(f'  running {n} ...', file=sys.stderr))
    if not results:
        print(f'error: no benchmark case matches {args.patterns}', file=sys.stderr)
        return 2
    print(format_table(results))
    if args.json:
        write_json(args.json, {'machine': machine_info(), 'cases': [asdict(r) for r in results]})
    return 0

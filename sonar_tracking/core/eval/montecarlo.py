"""Monte Carlo runs over processes, with the same results whatever the number of processes.

Run ``i`` of a study seeded ``seed`` draws from ``SeedSequence(seed).spawn(n)[i]``: its random
numbers depend only on the study seed and its index, so splitting runs over ``jobs`` processes
(or running them in one) gives identical results, returned in run order.

Worker processes start with the glibc allocator settings of :mod:`sonar_tracking.core.allocator`
(glibc reads them only at process start): when this process does not already run with them, the
workers come from a ``forkserver`` started with them instead of being forked from this process.
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Callable, Sequence

import numpy as np

from ..allocator import allocator_applied, allocator_env

__all__ = ['run_seeds', 'run_monte_carlo', 'Progress', 'default_jobs']


def run_seeds(seed: int, n_runs: int) -> list[np.random.SeedSequence]:
    """The seed sequence of every run of a study."""
    return np.random.SeedSequence(seed).spawn(n_runs)


def default_jobs() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


class Progress:
    """A one-line progress bar on stderr (only when stderr is a terminal, unless forced)."""

    def __init__(self, label: str, total: int, enabled: bool | None = None, stream=None) -> None:
        self.label, self.total, self.done = label, total, 0
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.t0 = time.monotonic()
        self._last = 0.0

    def update(self, n: int = 1) -> None:
        self.done += n
        now = time.monotonic()
        if not self.enabled or (now - self._last < 0.2 and self.done < self.total):
            return
        self._last = now
        elapsed = now - self.t0
        frac = self.done / max(self.total, 1)
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        bar = '#' * int(30 * frac)
        self.stream.write(f'\r{self.label} [{bar:<30s}] {self.done}/{self.total} runs, {elapsed:.0f} s, '
                          f'eta {eta:.0f} s ')
        if self.done >= self.total:
            self.stream.write('\n')
        self.stream.flush()


def _call(args: tuple) -> Any:
    fn, item, seed = args
    return fn(item, seed)


def run_monte_carlo(fn: Callable[[Any, np.random.SeedSequence], Any], item: Any, n_runs: int, seed: int,
                    jobs: int = 1, progress: Progress | None = None) -> list:
    """``[fn(item, seed_i) for i in range(n_runs)]``, spread over ``jobs`` processes.

    ``fn`` must be a module-level function (it is pickled to the worker processes).
    """
    seeds = run_seeds(seed, n_runs)
    tasks: Sequence[tuple] = [(fn, item, s) for s in seeds]
    if jobs <= 1 or n_runs <= 1:
        out = []
        for t in tasks:
            out.append(_call(t))
            if progress:
                progress.update()
        return out
    out = []
    with _worker_pool(jobs) as pool:
        for result in pool.map(_call, tasks, chunksize=max(1, n_runs // (8 * jobs))):
            out.append(result)
            if progress:
                progress.update()
    return out


@contextlib.contextmanager
def _worker_pool(jobs: int):
    """A process pool whose workers run with the allocator settings (see the module docstring)."""
    if allocator_applied():
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            yield pool
        return
    saved = dict(os.environ)
    # The forkserver, started at the first worker, inherits this environment; ours is restored after.
    os.environ.update(allocator_env())
    try:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context('forkserver')) as pool:
            yield pool
    finally:
        os.environ.clear()
        os.environ.update(saved)

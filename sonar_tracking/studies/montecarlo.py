"""Monte Carlo runs over processes or a Dask cluster, with the same results wherever they run.

Run ``i`` of a study seeded ``seed`` draws from ``SeedSequence(seed).spawn(n)[i]``: its random
numbers depend only on the study seed and its index, so running the runs in one process, over
``jobs`` local processes or on the workers of a Dask distributed cluster gives identical results,
returned in run order.

A :class:`RunPool` is where runs go: ``RunPool(jobs)`` is this process (``jobs <= 1``) or a pool
of ``jobs`` processes; ``RunPool(jobs, cluster='tcp://HOST:PORT')`` sends them to the Dask
scheduler at that address, ``cluster='local'`` to a ``LocalCluster`` of ``jobs`` worker processes
started for the pool. Dask (``pip install -r requirements-cluster.txt``) is imported only then.

With a checkpoint directory (``RunPool(jobs, checkpoint=DIR)``, ``--checkpoint DIR``) each finished
run is kept in ``DIR`` as soon as it ends, and a run already there is read back instead of run
again: a long study stopped part-way (a session that ends, a killed job) goes on where it stopped
when the same command runs again, and its results are the same bits. A run's file is named by a
hash of the run function, its item, its seed and a fingerprint of the code that computes it (the
run function's module and the package's sources but its command-line tools and ROS nodes, without
docstrings and comments; its ``config/`` files; the Python, numpy and scipy versions): after any
change of these the run is computed afresh. An unreadable file is logged and the run computed
again.

Local worker processes start with the glibc allocator settings of
:mod:`sonar_tracking.process` (glibc reads them only at process start): when this process
does not already run with them, the workers come from a ``forkserver`` started with them instead
of being forked from this process.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import logging
import multiprocessing
import multiprocessing.forkserver
import os
import pickle
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.process import allocator_applied, allocator_env

__all__ = ['run_seeds', 'run_monte_carlo', 'Progress', 'default_jobs', 'RunPool', 'ClusterUnavailable',
           'Checkpoint', 'code_fingerprint', 'add_pool_arguments', 'pool_from_args']

_log = logging.getLogger(__name__)
_MISSING = object()


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


# The package's command-line tools, ROS nodes and their helpers: no run computes in them (the run
# function's own module counts wherever it is).
_FRONT_ENDS = ('cli', 'nodes', 'ros')


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """A hash of what a run's result depends on besides its item, its seed and its function's module:
    the code of every ``.py`` file of the package but its front ends (``cli``, ``nodes``, ``ros``),
    every file of its ``config/`` directory, and the Python, numpy and scipy versions."""
    import scipy

    from sonar_tracking.resources import config_dirs
    h = hashlib.sha256(f'{sys.version_info[:2]} {np.__version__} {scipy.__version__}'.encode())
    package = Path(__file__).resolve().parent.parent
    for f in sorted(package.rglob('*.py')):
        if f.relative_to(package).parts[0] not in _FRONT_ENDS:
            h.update(str(f.relative_to(package)).encode() + _code_of(f))
    for config in [d for d in config_dirs() if (d / 'sensors').is_dir()][:1]:
        for f in sorted(config.rglob('*')):
            if f.is_file():
                h.update(str(f.relative_to(config)).encode() + f.read_bytes())
    return h.hexdigest()


@functools.cache
def _module_code(name: str) -> bytes:
    """The code of module ``name``'s source file (empty when it has none)."""
    spec = importlib.util.find_spec(name)
    origin = spec.origin if spec is not None else None
    return _code_of(Path(origin)) if origin and origin.endswith('.py') else b''


def _code_of(path: Path) -> bytes:
    """A Python file's syntax tree without docstrings (comments and layout are not in it): editing
    the words about the code leaves the fingerprint as it is."""
    source = path.read_bytes()
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return source
    for node in ast.walk(tree):
        body = getattr(node, 'body', None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            body[0] = ast.Pass()
    return ast.dump(tree).encode()


class Checkpoint:
    """Finished runs kept in a directory, one file each (module docstring)."""

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.reused = self.stored = 0

    def key(self, fn: Callable, item: Any, seed: np.random.SeedSequence) -> str:
        """The file name of run ``fn(item, seed)`` under the current code."""
        what = (fn.__module__, fn.__qualname__, item, seed.entropy, tuple(seed.spawn_key), seed.pool_size)
        return hashlib.sha256(pickle.dumps(what, protocol=4) + code_fingerprint().encode()
                              + _module_code(fn.__module__)).hexdigest()[:40]

    def get(self, key: str) -> Any:
        """The kept result of ``key``, or ``_MISSING`` (also, logged, when its file cannot be read)."""
        path = self.directory / f'{key}.pkl'
        if not path.is_file():
            return _MISSING
        try:
            with open(path, 'rb') as f:
                result = pickle.load(f)
        except Exception as exc:  # a truncated or foreign file: run again
            _log.warning('checkpoint %s unreadable (%s: %s); running it again', path, type(exc).__name__, exc)
            return _MISSING
        self.reused += 1
        return result

    def put(self, key: str, result: Any) -> None:
        """Keep ``result`` under ``key`` (written to a temporary file, then renamed: never half a file)."""
        path = self.directory / f'{key}.pkl'
        tmp = path.with_name(f'{path.name}.{os.getpid()}.tmp')
        with open(tmp, 'wb') as f:
            pickle.dump(result, f, protocol=4)
        os.replace(tmp, path)
        self.stored += 1


class ClusterUnavailable(RuntimeError):
    """A Dask cluster was asked for but Dask is not installed or the scheduler cannot be reached."""


class RunPool:
    """Where the runs of studies go: here, ``jobs`` local processes, or a Dask cluster.

    Use as a context manager; one pool serves several :meth:`map` calls (``desired-density`` runs
    one per candidate) without starting processes or a local cluster again.
    """

    def __init__(self, jobs: int = 1, cluster: str | None = None, checkpoint: str | Path | None = None) -> None:
        if jobs < 1:
            raise ValueError(f'jobs must be >= 1, not {jobs}')
        self.jobs, self.cluster = int(jobs), cluster or None
        self.checkpoint = Checkpoint(checkpoint) if checkpoint else None
        self._executor: ProcessPoolExecutor | None = None
        self._client = self._local = None

    def __enter__(self) -> RunPool:
        if self.cluster:
            self._connect()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def describe(self) -> str:
        """For the summary line: 'N processes' or the cluster and its worker count, and how many runs
        the checkpoint gave back."""
        if not self.cluster:
            where = f'{self.jobs} processes'
        else:
            workers = len(self._client.scheduler_info().get('workers', {})) if self._client else 0
            where = 'a local Dask cluster' if self.cluster == 'local' else f'the Dask cluster {self.cluster}'
            where = f'{where} ({workers} workers)'
        if self.checkpoint is not None:
            c = self.checkpoint
            where += f'; {c.reused} runs read back from {c.directory}, {c.stored} run and kept there'
        return where

    def _connect(self) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise ClusterUnavailable('--cluster needs Dask distributed: pip install -r requirements-cluster.txt '
                                     '(or pip install "dask[distributed]")') from None
        try:
            if self.cluster == 'local':
                self._local = LocalCluster(n_workers=self.jobs, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=40)
                self._client = Client(self._local)
            else:
                self._client = Client(self.cluster, timeout=30)
        except (OSError, TimeoutError) as exc:
            self.close()
            raise ClusterUnavailable(f'cannot reach the Dask scheduler {self.cluster}: {exc}') from None

    def map(self, fn: Callable[[Any, Any], Any], item: Any, seeds: Iterable, progress: Progress | None = None) -> list:
        """``[fn(item, s) for s in seeds]`` in that order, wherever the pool runs them.

        ``fn`` must be a module-level function of an installed package: workers import it by name."""
        seeds = list(seeds)
        if self.checkpoint is None:
            return self._map([(fn, item, s) for s in seeds], progress)
        cp = self.checkpoint
        keys = [cp.key(fn, item, s) for s in seeds]
        out = [cp.get(k) for k in keys]
        todo = [i for i, r in enumerate(out) if r is _MISSING]
        if progress and len(todo) < len(seeds):
            progress.update(len(seeds) - len(todo))

        def keep(j: int, result: Any) -> None:
            cp.put(keys[todo[j]], result)

        for j, result in enumerate(self._map([(fn, item, seeds[i]) for i in todo], progress, keep)):
            out[todo[j]] = result
        return out

    def _map(self, tasks: Sequence[tuple], progress: Progress | None,
             done: Callable[[int, Any], None] | None = None) -> list:
        """The results of ``tasks`` in their order; ``done(j, result)`` as each task ends (any order)."""
        if self.cluster:
            return self._map_cluster(tasks, progress, done)
        if self.jobs <= 1 or len(tasks) <= 1:
            out = []
            for j, t in enumerate(tasks):
                out.append(_call(t))
                if done:
                    done(j, out[-1])
                if progress:
                    progress.update()
            return out
        if self._executor is None:
            self._executor = _process_pool(self.jobs)
        if done is not None:
            # One task at a time, kept as it ends: a stopped study loses at most the runs under way.
            futures = {self._executor.submit(_call, t): j for j, t in enumerate(tasks)}
            results: list[Any] = [None] * len(tasks)
            for fut in as_completed(futures):
                j = futures[fut]
                results[j] = fut.result()
                done(j, results[j])
                if progress:
                    progress.update()
            return results
        out = []
        for result in self._executor.map(_call, tasks, chunksize=max(1, len(tasks) // (8 * self.jobs))):
            out.append(result)
            if progress:
                progress.update()
        return out

    def _map_cluster(self, tasks: Sequence[tuple], progress: Progress | None,
                     done: Callable[[int, Any], None] | None = None) -> list:
        from distributed import as_completed as completed
        if self._client is None:
            self._connect()
        futures = self._client.map(_call, tasks, pure=False)
        index = {f.key: j for j, f in enumerate(futures)}
        for fut in completed(futures):
            if done:
                done(index[fut.key], fut.result())
            if progress:
                progress.update()
        return self._client.gather(futures)  # run order, whatever order they finished in

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._local is not None:
            self._local.close()
            self._local = None


def _process_pool(jobs: int) -> ProcessPoolExecutor:
    """A process pool whose workers run with the allocator settings (see the module docstring)."""
    if allocator_applied():
        return ProcessPoolExecutor(max_workers=jobs)
    saved = dict(os.environ)
    os.environ.update(allocator_env())
    try:
        # The forkserver inherits this environment when it starts; ours is restored right after.
        multiprocessing.forkserver.ensure_running()
    finally:
        os.environ.clear()
        os.environ.update(saved)
    return ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context('forkserver'))


def run_monte_carlo(fn: Callable[[Any, np.random.SeedSequence], Any], item: Any, n_runs: int, seed: int,
                    jobs: int = 1, progress: Progress | None = None, pool: RunPool | None = None) -> list:
    """``[fn(item, seed_i) for i in range(n_runs)]`` (``seed_i`` from :func:`run_seeds`), on ``pool``
    or else over ``jobs`` local processes.

    ``fn`` must be a module-level function (it is pickled to the worker processes).
    """
    seeds = run_seeds(seed, n_runs)
    if pool is not None:
        return pool.map(fn, item, seeds, progress)
    with RunPool(jobs) as own:
        return own.map(fn, item, seeds, progress)


def add_pool_arguments(parser: Any) -> None:
    """``--jobs`` and ``--cluster`` of the ``sonar_eval`` studies."""
    parser.add_argument('--jobs', type=int, default=default_jobs(),
                        help='processes (default: all cores); with --cluster local, the workers')
    parser.add_argument('--cluster', default=None, metavar='tcp://HOST:PORT|local',
                        help='run the runs on the Dask scheduler at this address, or on a local Dask cluster of '
                        '--jobs workers; results are those of --jobs (needs requirements-cluster.txt)')
    parser.add_argument('--checkpoint', default=None, metavar='DIR',
                        help='keep every finished run in DIR and read it back when the same command runs again '
                        '(a stopped study goes on where it stopped; a change of the code, the settings or the '
                        'seeds runs afresh)')


def pool_from_args(args: Any) -> RunPool:
    """The :class:`RunPool` of parsed ``--jobs`` / ``--cluster`` / ``--checkpoint`` (not yet entered)."""
    return RunPool(args.jobs, getattr(args, 'cluster', None), getattr(args, 'checkpoint', None))

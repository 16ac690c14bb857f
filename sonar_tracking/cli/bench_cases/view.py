"""Pipeline throughput with and without ``sonar_view`` listening (issue: the live browser view).

The demo's stack (``config/stack_harbour.yaml``: the harbour simulator at full speed,
``active_detector``, ``imm_ipda_tracker``; 100 scans) runs with ``--record`` into a temporary bag,
``ROUNDS`` times each: plain, with ``--view`` (no browser connected: the view drops what it takes)
and with ``--view --always`` (the view logs every message, no browser), in turn so that the load
of a shared machine falls on all alike, each run in a DDS domain of its own. A run's sample
is its seconds per scan in steady state: the span between the ``SKIP``-th and the last ``/tracks``
message as the recorder received them, over the scans between (the first scans include the
processes settling, and a view without a browser unsubscribing once the pipeline runs). The ratios
of the medians to the plain one are the view's cost to the pipeline's throughput. Registered only
where the view extra (Rerun) is installed.
"""
from __future__ import annotations

import importlib.util
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from sonar_tracking.cli.bench import Case, register


def _port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


ROUNDS = 3
SKIP = 20
KINDS = (None, '', '--always')  # no view, the view, the view logging always
_RUNS: dict[str | None, list[float]] = {}


def _stack(view: str | None):
    def measure() -> list[float]:
        if view not in _RUNS:  # every kind runs here, in turn
            _RUNS.clear()
            for _ in range(ROUNDS):
                for kind in KINDS:
                    _RUNS.setdefault(kind, []).append(_seconds_per_scan(kind))
        return _RUNS.pop(view)
    return measure


def _seconds_per_scan(view: str | None) -> float:
    from sonar_tracking.io.bags import read_bag
    from sonar_tracking.resources import config_path
    from sonar_tracking.ros.runtime import private_domain
    tmp = Path(tempfile.mkdtemp(prefix='bench_view_'))
    try:
        cmd = [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', '--config',
               str(config_path('stack_harbour.yaml')), '--record', str(tmp / 'bag')]
        if view is not None:
            cmd += ['--view', f'--grpc-port {_port()} --web-port {_port()} {view}']
        private_domain()  # another pipeline on the machine would add its /tracks
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
        if r.returncode != 0:
            raise RuntimeError(f'the stack failed (status {r.returncode}):\n{r.stdout[-2000:]}')
        stamps = np.array([m.timestamp for m in read_bag(tmp / 'bag', ['/tracks'])], dtype=np.int64)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if len(stamps) < SKIP + 2:
        raise RuntimeError(f'the stack recorded {len(stamps)} /tracks messages, fewer than {SKIP + 2}')
    return float(stamps[-1] - stamps[SKIP]) * 1e-9 / (len(stamps) - 1 - SKIP)


if importlib.util.find_spec('rerun') is not None:
    register(Case(name='view.pipeline_plain', group='view', make=lambda: _stack(None), self_timed=True, repeats=1,
                  description='seconds per scan of the harbour stack at full speed (recorder receive times)'))
    register(Case(name='view.pipeline_with_view', group='view', make=lambda: _stack(''), self_timed=True,
                  repeats=1, compare_to='view.pipeline_plain',
                  description='the same with sonar_view listening, no browser connected'))
    register(Case(name='view.pipeline_with_view_always', group='view', make=lambda: _stack('--always'),
                  self_timed=True, repeats=1, compare_to='view.pipeline_plain',
                  description='the same with sonar_view --always logging every message, no browser connected'))

"""``sonar_view``: what it costs the pipeline, and how far a browser without GPU falls behind.

Pipeline cost (``view.pipeline_*``): the demo's stack (``config/stack_harbour.yaml``: the harbour
simulator at full speed, ``active_detector``, ``imm_ipda_tracker``; 100 scans) runs with
``--record`` into a temporary bag, ``ROUNDS`` times each: plain, with ``sonar_view`` listening and
no browser connected (the view drops what it takes), and with ``sonar_stack --view`` (the view logs
every message of the run, no browser), in turn so that the load of a shared machine falls on all
alike, each run in a DDS domain of its own. A run's sample is its seconds per scan in steady state:
the span between the ``SKIP``-th and the last ``/tracks`` message as the recorder received them,
over the scans between (the first scans include the processes settling). The ratios of the medians
to the plain one are the view's cost to the pipeline's throughput.

Browser lag (``view.browser_*``): ``sonar_view --always --qos reliable`` with the stack file's
``view_args`` (what ``sonar_stack --view`` runs) with Debian's headless Chromium (software WebGL, no
GPU) showing it in a 1600 x 1000 page; once the page's viewer is up, a stack runs. Every ``POLL``
seconds the page is asked for the newest ``log_time`` of the rows it holds (when the view logged
that row; :meth:`Chromium.newest_log_time`, from the viewer's state, so the page does no work for
it). The view also saves what it logs (``--save``); the lag at a poll is the age of the oldest row
the view had logged and the page did not hold yet
(:func:`~sonar_tracking.cli.view.browser.page_lags`). The lag while the stack runs counts the polls
from ``WARM_UP_S`` after the simulator starts (the page first builds its layout as the topics
appear; the largest lag before that is reported apart, as ``startup_lag_max_s``) to its last sector.
The end lag is from the simulator's last sector (the wall-clock stamp of its "finished" line) to the
first poll at which the page holds the last rows the view logged; ``view_s`` and ``page_s`` split it
into the view's part (its last row logged) and the page's. ``view.browser_{harbour,fls,imaging}``
run the shipped stacks as ``sonar_stack --view`` runs them (a full-speed simulator in real time, the
imaging one at a fifth of real time: its stack file's ``view_parameters``) for ``LIVE_SECONDS``
and report the end lag, and the median, 95th percentile and largest lag while they ran;
``view.browser_harbour_full_speed`` runs the harbour stack at its file's full speed.
``view.browser_rates`` (the harbour stack at ``RATES`` scans per second) and
``view.browser_imaging_rates`` (the imaging stack at ``IMAGING_RATES`` of real time) run for
``RATE_SECONDS`` of wall-clock time each, in rising order until the page falls more than
``KEEP_UP_S`` behind, and state the highest rate kept up with. Registered only where the view extra
(Rerun) and a Chromium are installed.
"""
from __future__ import annotations

import importlib.util
import math
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from sonar_tracking.cli.bench import Case, register

ROUNDS = 3
SKIP = 20
KINDS = (None, 'gated', 'stack')  # no view; a view without a browser (gated); sonar_stack --view
_RUNS: dict[str | None, list[float]] = {}

POLL = 0.25
WARM_UP_S = 10.0
KEEP_UP_S = 2.0
RATES = (1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
IMAGING_RATES = (0.1, 0.2, 0.3, 0.5)   # of real time: 2, 4, 6 and 10 frames a second
RATE_SECONDS = 20.0
LIVE_SECONDS = 30.0
_EXTRA: dict[str, dict] = {}


def _stack(kind: str | None):
    def measure() -> list[float]:
        if kind not in _RUNS:  # every kind runs here, in turn
            _RUNS.clear()
            for _ in range(ROUNDS):
                for k in KINDS:
                    _RUNS.setdefault(k, []).append(_seconds_per_scan(k))
        return _RUNS.pop(kind)
    return measure


def _wait_line(log: Path, pattern: str, proc: subprocess.Popen, timeout: float) -> re.Match:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        m = re.search(pattern, log.read_text())
        if m:
            return m
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    raise RuntimeError(f'no {pattern!r} in:\n{log.read_text()[-2000:]}')


def _stop(proc: subprocess.Popen) -> int:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode


def _seconds_per_scan(kind: str | None) -> float:
    from sonar_tracking import process
    from sonar_tracking.io.bags import read_bag
    from sonar_tracking.resources import config_path
    from sonar_tracking.ros.runtime import private_domain
    tmp = Path(tempfile.mkdtemp(prefix='bench_view_'))
    try:
        cmd = [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', '--config',
               str(config_path('stack_harbour.yaml')), '--record', str(tmp / 'bag')]
        private_domain()  # another pipeline on the machine would add its /tracks
        view = None
        if kind == 'gated':  # the view's own default: it logs only while a browser is connected
            view = subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.sonar_view'],
                                    stdout=(tmp / 'view.log').open('w'), stderr=subprocess.STDOUT,
                                    start_new_session=True, preexec_fn=process.child_dies_with_parent())
            _wait_line(tmp / 'view.log', r'view: ', view, 60)
        elif kind == 'stack':
            cmd += ['--view']
        log = tmp / 'stack.log'
        stack = subprocess.Popen(cmd, stdout=log.open('w'), stderr=subprocess.STDOUT, start_new_session=True,
                                 preexec_fn=process.child_dies_with_parent())
        try:
            if kind == 'stack':  # the stack keeps its view after the run until told to stop
                _wait_line(log, r'keeps the whole run', stack, 300)
                _stop(stack)
            else:
                stack.wait(300)
        finally:
            _stop(stack)
            if view is not None:
                _stop(view)
        if stack.returncode != 0:
            raise RuntimeError(f'the stack failed (status {stack.returncode}):\n{log.read_text()[-2000:]}')
        stamps = np.array([m.timestamp for m in read_bag(tmp / 'bag', ['/tracks'])], dtype=np.int64)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if len(stamps) < SKIP + 2:
        raise RuntimeError(f'the stack recorded {len(stamps)} /tracks messages, fewer than {SKIP + 2}')
    return float(stamps[-1] - stamps[SKIP]) * 1e-9 / (len(stamps) - 1 - SKIP)


def browser_lag(stack: str, settings: list[str], view_args: tuple[str, ...] = (), timeout: float = 600.0) -> dict:
    """Run ``stack`` (a shipped stack's name, with ``--set`` settings) while headless Chromium shows
    ``sonar_view`` of it; returns ``run_lags`` (the page's lag at each poll while the stack ran [s]),
    ``end_lag`` (the simulator's last sector to the page holding the last rows [s]), ``worst`` (the
    largest of those, what ``KEEP_UP_S`` bounds), ``startup_lag_max`` and ``scans``."""
    from sonar_tracking import process
    from sonar_tracking.cli.sonar_stack import find_stack, load_stack, view_spec
    from sonar_tracking.cli.view.browser import Chromium, log_times, page_lags
    from sonar_tracking.ros.runtime import private_domain
    private_domain()
    tmp = Path(tempfile.mkdtemp(prefix='bench_view_browser_'))
    procs: list[subprocess.Popen] = []

    def start(args: list[str], log: str) -> subprocess.Popen:
        procs.append(subprocess.Popen([sys.executable, '-m', *args], stdout=(tmp / log).open('w'),
                                      stderr=subprocess.STDOUT, start_new_session=True,
                                      preexec_fn=process.child_dies_with_parent()))
        return procs[-1]
    try:
        saved = tmp / 'view.rrd'   # every row the view logged, with its log_time
        config = load_stack(find_stack(stack))   # the view and the nodes as sonar_stack --view runs them
        settings = [f'{spec.name}.{k}={v}' for spec in config.nodes for k, v in spec.view_parameters.items()] + settings
        viewer = view_spec(config, shlex.join(['--save', str(saved), *view_args]))
        view = start(['sonar_tracking.cli.sonar_view', *viewer.extra_args], 'view.log')
        url = _wait_line(tmp / 'view.log', r'view: (\S+)', view, 60).group(1)
        with Chromium() as page:
            page.open(url)
            deadline = time.monotonic() + 120
            while page.recording() is None:  # the viewer runs and streams from the view
                if time.monotonic() > deadline:
                    raise RuntimeError('the page did not start its viewer within 120 s')
                time.sleep(0.25)
            sets = [a for s in settings for a in ('--set', s)]
            run = start(['sonar_tracking.cli.sonar_stack', stack, *sets], 'stack.log')
            polls: list[tuple[float, float | None, bool]] = []
            steady, last, deadline = 0, None, time.monotonic() + timeout
            while time.monotonic() < deadline:
                time.sleep(POLL)
                running = run.poll() is None
                polls.append((time.time(), page.newest_log_time(), running))
                latest = polls[-1][1]
                steady = steady + 1 if not running and latest == last else 0
                last = latest
                if steady >= int(3.0 / POLL):  # the stack ended and the page got nothing new for 3 s
                    break
            text = (tmp / 'stack.log').read_text()
        m = re.search(r'\[seaking_sim\] \[INFO\] \[(\d+\.\d+)\] \[seaking_sim\]: .*finished after (\d+)', text)
        if m is None or run.returncode != 0:
            raise RuntimeError(f'the stack did not finish (status {run.returncode}):\n{text[-2000:]}')
        finished, scans = float(m.group(1)), int(m.group(2))
        logged = log_times(saved)
        final = logged[-1]
        reached = next((when for when, t, _ in polls if t is not None and t >= final), math.inf)
        started = float(re.search(r'\[seaking_sim\] \[INFO\] \[(\d+\.\d+)\] \[seaking_sim\]: starting', text).group(1))
        lags = page_lags([(when, t) for when, t, _ in polls], logged)
        run_lags = [lag for lag, (when, _, running) in zip(lags, polls, strict=True)
                    if running and started + WARM_UP_S <= when <= finished]
        startup = [lag for lag, (when, _, running) in zip(lags, polls, strict=True)
                   if running and when < started + WARM_UP_S]
        end_lag = max(0.0, reached - finished)
        return {'run_lags': run_lags, 'end_lag': end_lag, 'worst': max([end_lag, *run_lags]), 'scans': scans,
                'view_lag': final - finished, 'page_lag': reached - final, 'startup_lag_max': max(startup, default=0.0)}
    finally:
        for p in procs:
            _stop(p)
        shutil.rmtree(tmp, ignore_errors=True)


def _shipped(name: str, stack: str, settings: list[str]):
    def measure() -> list[float]:
        got = browser_lag(stack, settings)
        lags = got['run_lags'] or [float('nan')]
        _EXTRA[name] = {'scans': got['scans'], 'run_lag_median_s': float(np.median(lags)),
                        'run_lag_p95_s': float(np.percentile(lags, 95)), 'run_lag_max_s': max(lags),
                        'end_lag_s': got['end_lag'], 'view_s': got['view_lag'], 'page_s': got['page_lag'],
                        'startup_lag_max_s': got['startup_lag_max']}
        return [got['worst']]
    return measure


def _rates(name: str, stack: str, rates: tuple[float, ...], per_rate: float, unit: str):
    """The case ``name``: ``stack`` with its simulator at ``rates`` of real time (``per_rate`` ``unit``
    each) for ``RATE_SECONDS`` of wall-clock time each, in rising order until the worst lag exceeds
    ``KEEP_UP_S``; returns the worst lag at the highest rate kept."""
    def measure() -> list[float]:
        lags: dict[float, dict] = {}
        kept = None
        for rate in rates:
            # the harbour scenario's sectors are 1 s of simulated time each; at least 10 of them
            sim_s = max(10.0, rate * RATE_SECONDS) if stack == 'harbour' else rate * (RATE_SECONDS + WARM_UP_S)
            got = browser_lag(stack, [f'seaking_sim.rate={rate:g}', f'seaking_sim.duration={sim_s:g}'])
            worst = got['worst']
            lags[rate] = {'end': got['end_lag'], 'worst': worst,
                          'median': float(np.median(got['run_lags'] or [np.nan]))}
            if worst > KEEP_UP_S:
                break
            kept = rate
        _EXTRA[name] = {
            f'highest_rate_kept_{unit.replace("/", "_per_")}': kept * per_rate if kept is not None else 0.0,
            'lag_by_rate_s (median/worst)': ', '.join(f'{r * per_rate:g} {unit} {v["median"]:.2f}/{v["worst"]:.2f}'
                                                      for r, v in lags.items())}
        return [lags[kept]['worst'] if kept is not None else lags[rates[0]]['worst']]
    return measure


def _extra(name: str):
    return lambda r: _EXTRA.pop(name, {})


if importlib.util.find_spec('rerun') is not None:
    register(Case(name='view.pipeline_plain', group='view', make=lambda: _stack(None), self_timed=True, repeats=1,
                  description='seconds per scan of the harbour stack at full speed (recorder receive times)'))
    register(Case(name='view.pipeline_with_view', group='view', make=lambda: _stack('gated'), self_timed=True,
                  repeats=1, compare_to='view.pipeline_plain',
                  description='the same with sonar_view listening, no browser connected'))
    register(Case(name='view.pipeline_with_stack_view', group='view', make=lambda: _stack('stack'),
                  self_timed=True, repeats=1, compare_to='view.pipeline_plain',
                  description='the same with sonar_stack --view (the view logs the whole run), no browser'))
    if shutil.which('chromium') is not None:
        for _name, _stack_name, _settings, _what in (
                ('view.browser_harbour', 'harbour', ['seaking_sim.rate=1', f'seaking_sim.duration={LIVE_SECONDS:g}'],
                 f'the harbour stack as --view runs it (real time, 1 scan/s), {LIVE_SECONDS:g} scans'),
                ('view.browser_fls', 'fls', ['seaking_sim.rate=1', f'seaking_sim.duration={LIVE_SECONDS:g}'],
                 f'the FLS stack as --view runs it (real time), {LIVE_SECONDS:g} s'),
                ('view.browser_imaging', 'imaging', [f'seaking_sim.duration={LIVE_SECONDS / 5:g}'],
                 f'the imaging stack as --view runs it (4 frames/s), {LIVE_SECONDS:g} s'),
                ('view.browser_harbour_full_speed', 'harbour', [],
                 'the harbour stack at full speed (its file\'s rate 0, 100 scans)')):
            register(Case(name=_name, group='view', make=lambda n=_name, s=_stack_name, a=_settings: _shipped(n, s, a),
                          self_timed=True, repeats=1, limit_s=KEEP_UP_S, derived=_extra(_name),
                          description=f'headless Chromium: the page\'s worst lag behind the stack, while it ran '
                                      f'and from its last sector to the page holding it, {_what}'))
        register(Case(name='view.browser_rates', group='view',
                      make=lambda: _rates('view.browser_rates', 'harbour', RATES, 1.0, 'scans/s'), self_timed=True,
                      repeats=1, limit_s=KEEP_UP_S, derived=_extra('view.browser_rates'),
                      description='headless Chromium: the harbour stack at rising rates; the worst lag at the '
                      'highest rate it keeps up with (note: that rate)'))
        register(Case(name='view.browser_imaging_rates', group='view',
                      make=lambda: _rates('view.browser_imaging_rates', 'imaging', IMAGING_RATES, 20.0, 'frames/s'),
                      self_timed=True, repeats=1, limit_s=KEEP_UP_S, derived=_extra('view.browser_imaging_rates'),
                      description='headless Chromium: the imaging stack at 2, 4, 6 and 10 frames a second; the '
                      'worst lag at the highest frame rate it keeps up with (note: that rate)'))

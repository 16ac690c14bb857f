"""Where runs go (:mod:`sonar_tracking.studies.montecarlo`): in process, a process pool and a local
Dask cluster give the same results in run order, with the same progress bar; a missing Dask says
how to install it."""
from __future__ import annotations

import io
import json
import sys

import numpy as np
import pytest

from sonar_tracking.cli.sonar_eval import main
from sonar_tracking.studies.esc_study import StudyConfig, parse_methods, run_once
from sonar_tracking.studies.montecarlo import ClusterUnavailable, Progress, RunPool, run_monte_carlo

# Dask workers import the run function by name: it must live in the package, not in this test module.
STUDY = StudyConfig(scans=6, methods=parse_methods('esc,fixed:4'))


def same(a: list[dict], b: list[dict]) -> bool:
    return len(a) == len(b) and all(x.keys() == y.keys() and all(
        np.array_equal(x[m][k], y[m][k], equal_nan=True) for m in x for k in x[m]) for x, y in zip(a, b))


def strip(result: dict) -> dict:
    return {k: v for k, v in result.items() if k not in ('wall_s', 'jobs')}


def test_jobs_and_in_process_runs_agree_and_keep_run_order():
    one = run_monte_carlo(run_once, STUDY, 3, seed=9, jobs=1)
    two = run_monte_carlo(run_once, STUDY, 3, seed=9, jobs=2)
    assert same(one, two) and len(two) == 3
    assert not same(one[:1], one[1:2])


def test_a_study_on_a_local_dask_cluster_equals_the_same_study_with_two_jobs(tmp_path, capsys):
    pytest.importorskip('distributed', reason='requirements-cluster.txt (make test installs it)')
    args = ['scenario1', '--runs', '4', '--scans', '20', '--seed', '3', '--methods', 'esc,fixed:4']
    assert main([*args, '--jobs', '2', '--json', str(tmp_path / 'jobs.json')]) == 0
    assert main([*args, '--jobs', '2', '--cluster', 'local', '--json', str(tmp_path / 'dask.json')]) == 0
    assert 'on a local Dask cluster (2 workers)' in capsys.readouterr().out
    jobs, dask = (json.loads((tmp_path / f).read_text()) for f in ('jobs.json', 'dask.json'))
    assert strip(dask) == strip(jobs)


def test_the_cluster_fills_the_progress_bar_and_returns_runs_in_order():
    pytest.importorskip('distributed', reason='requirements-cluster.txt (make test installs it)')
    stream = io.StringIO()
    progress = Progress('t', 6, enabled=True, stream=stream)
    with RunPool(2, cluster='local') as pool:
        on_cluster = run_monte_carlo(run_once, STUDY, 6, seed=4, progress=progress, pool=pool)
        again = pool.map(run_once, STUDY, np.random.SeedSequence(4).spawn(6))  # the pool serves several maps
    here = run_monte_carlo(run_once, STUDY, 6, seed=4)
    assert same(here, on_cluster) and same(here, again)
    assert progress.done == 6 and stream.getvalue().rstrip().endswith('eta 0 s')


def test_without_dask_the_error_says_how_to_install(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, 'distributed', None)  # import distributed -> ImportError
    with pytest.raises(ClusterUnavailable, match='requirements-cluster.txt'):
        RunPool(2, cluster='local').__enter__()
    assert main(['scenario1', '--runs', '2', '--scans', '6', '--cluster', 'local', '--jobs', '1']) == 2
    assert 'pip install -r requirements-cluster.txt' in capsys.readouterr().err


def test_bad_jobs_are_refused():
    with pytest.raises(ValueError, match='jobs must be >= 1'):
        RunPool(0)

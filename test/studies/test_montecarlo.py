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


# -- checkpoints -------------------------------------------------------------------------------------

CALLS: list[int] = []


def counted(item, seed):
    """run_once, counted (jobs=1 runs it in this process)."""
    CALLS.append(1)
    return run_once(item, seed)


def test_a_checkpoint_gives_back_finished_runs_without_running_them_again(tmp_path):
    CALLS.clear()
    with RunPool(1, checkpoint=tmp_path) as pool:
        first = run_monte_carlo(counted, STUDY, 3, seed=9, pool=pool)
    assert len(CALLS) == 3 and len(list(tmp_path.glob('*.pkl'))) == 3
    with RunPool(1, checkpoint=tmp_path) as pool:
        again = run_monte_carlo(counted, STUDY, 3, seed=9, pool=pool)
        assert pool.checkpoint.reused == 3 and pool.checkpoint.stored == 0
        assert '3 runs read back' in pool.describe()
    assert len(CALLS) == 3 and same(first, again)
    assert same(first, run_monte_carlo(run_once, STUDY, 3, seed=9))


def test_a_stopped_study_goes_on_where_it_stopped_over_processes(tmp_path):
    with RunPool(2, checkpoint=tmp_path) as pool:
        run_monte_carlo(run_once, STUDY, 2, seed=5, pool=pool)     # the first two runs of four, then stopped
    with RunPool(2, checkpoint=tmp_path) as pool:
        resumed = run_monte_carlo(run_once, STUDY, 4, seed=5, pool=pool)
        assert (pool.checkpoint.reused, pool.checkpoint.stored) == (2, 2)
    assert same(resumed, run_monte_carlo(run_once, STUDY, 4, seed=5))


def test_other_settings_seeds_or_code_run_afresh(tmp_path, monkeypatch):
    from sonar_tracking.studies import montecarlo
    CALLS.clear()
    with RunPool(1, checkpoint=tmp_path) as pool:
        run_monte_carlo(counted, STUDY, 2, seed=9, pool=pool)
        run_monte_carlo(counted, StudyConfig(scans=7, methods=STUDY.methods), 2, seed=9, pool=pool)
        run_monte_carlo(counted, STUDY, 2, seed=10, pool=pool)
        assert len(CALLS) == 6 and pool.checkpoint.reused == 0
        monkeypatch.setattr(montecarlo, 'code_fingerprint', lambda: 'other code')
        run_monte_carlo(counted, STUDY, 2, seed=9, pool=pool)
        assert len(CALLS) == 8 and pool.checkpoint.reused == 0


def test_an_unreadable_checkpoint_file_is_logged_and_the_run_done_again(tmp_path, caplog):
    with RunPool(1, checkpoint=tmp_path) as pool:
        first = run_monte_carlo(run_once, STUDY, 2, seed=9, pool=pool)
    victim = sorted(tmp_path.glob('*.pkl'))[0]
    victim.write_bytes(victim.read_bytes()[:20])                     # a file cut short
    with caplog.at_level('WARNING'), RunPool(1, checkpoint=tmp_path) as pool:
        again = run_monte_carlo(run_once, STUDY, 2, seed=9, pool=pool)
        assert (pool.checkpoint.reused, pool.checkpoint.stored) == (1, 1)
    assert same(first, again)
    assert any('unreadable' in r.getMessage() and victim.name in r.getMessage() for r in caplog.records)


def test_the_study_command_with_a_checkpoint_gives_the_same_json_again(tmp_path, capsys):
    args = ['scenario1', '--runs', '2', '--scans', '6', '--seed', '3', '--methods', 'esc,fixed:4', '--jobs', '1',
            '--checkpoint', str(tmp_path / 'cp')]
    assert main([*args, '--json', str(tmp_path / 'a.json')]) == 0
    assert main([*args, '--json', str(tmp_path / 'b.json')]) == 0
    assert '2 runs read back' in capsys.readouterr().out
    a, b = (json.loads((tmp_path / f).read_text()) for f in ('a.json', 'b.json'))
    assert strip(a) == strip(b)


def test_the_fingerprint_ignores_docstrings_and_comments_but_not_code(tmp_path):
    from sonar_tracking.studies.montecarlo import _code_of
    files = {'a': '"""Module."""\ndef f(x):\n    """Twice x."""\n    return 2 * x  # doubled\n',
             'b': '"""Module, reworded."""\ndef f(x):\n    """x times two."""\n\n    return 2 * x\n',
             'c': '"""Module."""\ndef f(x):\n    """Twice x."""\n    return 3 * x  # doubled\n'}
    for name, text in files.items():
        (tmp_path / f'{name}.py').write_text(text)
    a, b, c = (_code_of(tmp_path / f'{n}.py') for n in 'abc')
    assert a == b and a != c

"""``sonar_eval fls``: the FLS paper's tracking study (§5) on simulated Table 5 situations and the sea trial.

``sonar_eval fls --situation N --runs R --seed S --methods af,mf,wf,ekf,pf --json FILE [--plot FILE.png]``
runs situation N (1-14) of Table 5 (static SeaKing 675 kHz in a tank, 300 particles, §5.1), or with
``--preset sea-trial`` the sea trial of §5.2 (AUV at 0.5 m/s, towed targets with current
disturbance, 200 particles, §5.2.1), R times over ``--jobs`` processes or a Dask cluster
(``--cluster``; :func:`~sonar_tracking.studies.montecarlo.run_monte_carlo`: the results depend only
on ``--seed``). Every run simulates the frames once and gives the same frames to every method
(:mod:`sonar_tracking.studies.fls_study`): GPF with adaptive (af), multiplicative (mf) or
weighted (wf) fusion, the SIR particle filter (pf) and the EKF on the regions (ekf).

The JSON holds ``{"methods": {NAME: {"cle_mean": [per target], "cle": [[per frame] per target],
"lost_frames": [per target], ...}}, "wall_s": t}`` plus the frame stamps, target ids, identity
rates through a crossing (situations 8-11, 13 and the sea trial), every run's mean CLE
(``cle_run``) and, for every method after the first, the paired difference of those to the first
method's with its 95 % confidence interval (``paired_with_first``), and the settings; the plot shows
trajectories and CLE curves per target in the style of Figures 13, 16 and 19.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.cli._output import table_command, write_json, write_plot

__all__ = ['add_arguments', 'main_args', 'run_study', 'study_for', 'plot', 'add_table_arguments', 'main_table']

SEA_TRIAL = 'sea-trial'

#: Settings of the sea-trial preset: 200 particles (§5.2.1); targets 0.5-1 m/s pushed about by the
#: current, so a faster velocity prior and more process noise than in the tank (ours).
SEA_TRIAL_SETTINGS = {'particles': 200, 'birth.sigma_speed': 0.8, 'motion.noise': 0.02, 'lost.max_std': 3.0}


def add_arguments(parser: Any) -> None:
    """Arguments of ``sonar_eval fls``."""
    from sonar_tracking.studies.fls_study import METHODS
    from sonar_tracking.studies.montecarlo import add_pool_arguments
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument('--situation', type=int, choices=range(1, 15), metavar='N',
                       help='FLS paper Table 5 situation 1-14 (tank, static sonar)')
    which.add_argument('--preset', choices=(SEA_TRIAL,), help='the sea trial of §5.2 (moving AUV, 200 particles)')
    parser.add_argument('--runs', type=int, default=10, help='Monte Carlo runs (default 10)')
    parser.add_argument('--seed', type=int, default=0, help='study seed: run i uses SeedSequence(seed).spawn(runs)[i]')
    parser.add_argument('--methods', default=','.join(METHODS),
                        help=f'comma list of {",".join(METHODS)} (default all)')
    parser.add_argument('--particles', type=int, default=None, help='particles per track (default 300, sea trial 200)')
    parser.add_argument('--sensor', choices=('seaking675', 'seaking325'), default='seaking675',
                        help='SeaKing model (default seaking675)')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, required=True, help='write the results to this JSON file')
    parser.add_argument('--plot', type=Path, default=None, help='also draw trajectories and CLE curves to this PNG')


def study_for(situation: int | None, preset: str | None, methods: tuple[str, ...], particles: int | None = None,
              sensor: str = 'seaking675'):
    """The :class:`~sonar_tracking.studies.fls_study.FlsStudy` of a situation or the sea-trial preset."""
    from sonar_tracking.core.gpf import GpfConfig
    from sonar_tracking.studies.fls_study import FlsStudy, situation_scenario
    flat: dict[str, Any] = dict(SEA_TRIAL_SETTINGS) if preset == SEA_TRIAL else {}
    if particles is not None:
        flat['particles'] = particles
    scenario = situation_scenario(SEA_TRIAL if preset == SEA_TRIAL else situation)
    return FlsStudy(scenario, methods=methods, config=GpfConfig.from_flat(flat), preset=sensor)


def run_study(study, runs: int, seed: int, jobs: int = 1, progress=None, pool=None) -> dict:
    """Run ``study`` ``runs`` times (on ``pool``, else over ``jobs`` processes); the JSON-ready result
    (module docstring)."""
    from sonar_tracking.studies.fls_study import run_once, summarise
    from sonar_tracking.studies.montecarlo import run_monte_carlo
    t0 = time.perf_counter()
    results = run_monte_carlo(run_once, study, runs, seed, jobs, progress, pool)
    wall = time.perf_counter() - t0
    first = results[0]
    return {
        'scenario': study.scenario, 'runs': runs, 'seed': seed, 'jobs': jobs,
        'target_ids': [int(i) for i in first['ids']],
        'stamps': [float(s) for s in first['stamps']],
        'config': {k: (list(v) if isinstance(v, tuple) else v) for k, v in study.config.flat().items()},
        'methods': summarise(study, results),
        'example': _example(first, study.methods),
        'wall_s': wall,
    }


def _example(run: dict, methods: tuple[str, ...]) -> dict:
    """Run 0's truth and each method's tracks (for the trajectory plots)."""
    return {'truth': np.round(run['truth'][:, :, :2], 4).tolist(),
            'tracks': {m: [np.round(t, 4).tolist() for t in run['tracks'][m]] for m in methods}}


_STYLE = {'af': ('C3', '-', 'proposed (AF)'), 'af18': ('C5', '-', 'AF, eq. 18 alone'), 'mf': ('C0', '--', 'MF'),
          'wf': ('C2', '-.', 'WF'),
          'pf': ('C1', ':', 'PF'), 'ekf': ('C4', (0, (5, 1, 1, 1)), 'EKF')}


def plot(result: dict, path: Path) -> None:
    """Per target: its true path and each method's track in run 0 (Figures 13a, 15, 18), and the
    mean CLE per frame over the runs (Figures 13b, 16, 19)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    ids = result['target_ids']
    g = max(1, len(ids))
    fig, axes = plt.subplots(2, g, figsize=(5.5 * g, 8.5), squeeze=False)
    truth = np.array(result['example']['truth'])                    # (F, G, 2)
    frames = np.arange(1, len(result['stamps']) + 1)
    for t in range(len(ids)):
        ax, bx = axes[0, t], axes[1, t]
        ax.plot(truth[:, t, 1], truth[:, t, 0], 'k-o', ms=3, lw=2, label='real')
        for m, res in result['methods'].items():
            color, ls, label = _STYLE.get(m, ('k', '-', m))
            path_xy = _owner_path(result['example']['tracks'][m], truth, t)
            if len(path_xy):
                ax.plot(path_xy[:, 1], path_xy[:, 0], color=color, ls=ls, marker='.', label=label)
            cle = np.array([np.nan if v is None else v for v in res['cle'][t]])
            bx.plot(frames, cle, color=color, ls=ls, marker='.', label=f'{label}: mean {_fmt(res["cle_mean"][t])} m')
        ax.set_xlabel('y (left) [m]')
        ax.set_ylabel('x (forward) [m]')
        ax.invert_xaxis()
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_title(f'target {ids[t]}: trajectories (run 0)')
        ax.legend(fontsize=7)
        bx.set_xlabel('frame')
        bx.set_ylabel('CLE [m] (eq. 19), mean over runs')
        bx.set_title(f'target {ids[t]}: CLE, {result["runs"]} runs')
        bx.legend(fontsize=7)
    fig.suptitle(f'{result["scenario"]}: ' + ', '.join(f'{m} identity kept {r["identity_kept_rate"]:.0%}'
                                                      for m, r in result['methods'].items()
                                                      if r.get('identity_kept_rate') is not None))
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _owner_path(tracks: list, truth: np.ndarray, t: int, gate: float = 1.5) -> np.ndarray:
    """The path of the track nearest target ``t`` in each frame (within ``gate``)."""
    out = []
    for k, rows in enumerate(tracks):
        rows = np.asarray(rows, dtype=float).reshape(-1, 3)
        if len(rows):
            d = np.hypot(rows[:, 1] - truth[k, t, 0], rows[:, 2] - truth[k, t, 1])
            j = int(np.argmin(d))
            if d[j] < gate:
                out.append(rows[j, 1:])
    return np.array(out).reshape(-1, 2)


def _fmt(v) -> str:
    return 'n/a' if v is None else f'{v:.2f}'


def _paired(p: dict | None) -> str:
    if p is None:
        return ''
    if p['difference'] is None:
        return 'n/a'
    return f'{p["difference"]:+.3f}' + ('' if p['ci95'] is None else f' +/- {p["ci95"]:.3f}')


def main_args(args: Any) -> int:
    """Run ``sonar_eval fls`` with parsed arguments; returns the exit status."""
    from sonar_tracking.studies.fls_study import parse_methods
    from sonar_tracking.studies.montecarlo import ClusterUnavailable, Progress, pool_from_args
    try:
        methods = parse_methods(args.methods)
    except ValueError as exc:
        print(f'error: --methods: {exc}', file=sys.stderr)
        return 2
    if args.runs < 1 or args.jobs < 1:
        print('error: --runs and --jobs must be >= 1', file=sys.stderr)
        return 2
    if args.particles is not None and args.particles < 10:
        print('error: --particles must be >= 10', file=sys.stderr)
        return 2
    study = study_for(args.situation, args.preset, methods, args.particles, args.sensor)
    label = args.preset or f'situation {args.situation}'
    try:
        with pool_from_args(args) as pool:
            result = run_study(study, args.runs, args.seed, args.jobs, Progress(label, args.runs), pool)
            where = pool.describe()
    except ClusterUnavailable as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    result['situation'] = args.preset or args.situation
    print(f'{label} ({study.scenario}): {args.runs} runs in {result["wall_s"]:.1f} s on {where}')
    ids = result['target_ids']
    head = ''.join(f'{"CLE t" + str(i):>10s}{"lost t" + str(i):>9s}' for i in ids)
    first = methods[0]
    print(f'{"method":8s}{head}{"identity kept":>15s}{first + " - method [m]":>22s}')
    for m, r in result['methods'].items():
        cells = ''.join(f'{_fmt(c):>10s}{lf:9.1f}' for c, lf in zip(r['cle_mean'], r['lost_frames']))
        ident = r.get('identity_kept_rate')
        ident = 'n/a' if ident is None else f'{ident:.0%}'
        print(f'{m:8s}{cells}{ident:>15s}{_paired(r.get("paired_with_first")):>22s}')
    if len(methods) > 1:
        print(f'{first} - method: paired difference of the runs\' mean CLE, with its 95 % confidence interval')
    write_json(args.json, result, allow_nan=False)
    if args.plot:
        write_plot(args.plot, plot, result)
    return 0


if __name__ == '__main__':  # pragma: no cover - use sonar_eval fls
    import argparse
    p = argparse.ArgumentParser(prog='sonar_eval fls', description=__doc__.split('\n\n')[0])
    add_arguments(p)
    raise SystemExit(main_args(p.parse_args()))


def add_table_arguments(parser: Any) -> None:
    """Arguments of ``sonar_eval fls-table``."""
    from sonar_tracking.studies.evidence import add_seed_arguments
    from sonar_tracking.studies.fls_table import TABLE_METHODS, TABLE_SITUATIONS
    from sonar_tracking.studies.montecarlo import add_pool_arguments
    add_seed_arguments(parser, calibration='5101', evaluation='5201,5202', runs=300, calibration_runs=40)
    parser.add_argument('--situations', default=','.join(map(str, TABLE_SITUATIONS)),
                        help='comma list of Table 5 situations (default the crossings 8-11)')
    parser.add_argument('--methods', default=','.join(TABLE_METHODS),
                        help='comma list; the first is paired with each other (default af,af18,mf,wf)')
    parser.add_argument('--hits', default='1,2,3,4',
                        help='birth.confirm_hits values tried on the calibration runs (default 1,2,3,4)')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write the results here')


def main_table(args: Any) -> int:
    """Run the FLS comparison out of sample; print the docs/results tables."""
    from sonar_tracking.studies.evidence import seed_split_from_args
    from sonar_tracking.studies.fls_study import parse_methods
    from sonar_tracking.studies.fls_table import TUNED_ON, format_table, run_table
    try:
        methods = parse_methods(args.methods)
        situations = [int(n) for n in args.situations.split(',') if n.strip()]
        hits = tuple(int(h) for h in args.hits.split(',') if h.strip())
        split = seed_split_from_args(args, tuned_on=TUNED_ON)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if (args.jobs < 1 or not situations or any(not 1 <= n <= 14 for n in situations) or not hits
            or any(not 1 <= h <= 1000 for h in hits) or len(set(hits)) != len(hits)):
        print('error: need --jobs >= 1, situations among 1-14 and distinct --hits among 1-1000', file=sys.stderr)
        return 2
    return table_command('fls-table', args, lambda pool: run_table(split, args.runs, args.calibration_runs, pool,
                                                                    situations, methods, hits), format_table)

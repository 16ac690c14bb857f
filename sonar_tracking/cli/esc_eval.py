"""``sonar_eval scenario1 | scenario2 | desired-density``: the ESC paper's simulations (§4-§5).

Each command is ``add_*_arguments(parser)`` + ``main_*(args) -> int``, wired in ``sonar_eval``.
Runs spread over ``--jobs`` processes or a Dask cluster (``--cluster``); the results depend only on
``--seed``.
"""
from __future__ import annotations

import datetime
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from sonar_tracking.cli._output import seed_split_or_none, table_command, write_json, write_plot
from sonar_tracking.studies import algorithm1
from sonar_tracking.studies.esc_study import PAPER_DESIRED_DENSITY, StudyConfig, parse_methods, run_once, summarise
from sonar_tracking.studies.montecarlo import (
    ClusterUnavailable,
    Progress,
    add_pool_arguments,
    pool_from_args,
    run_monte_carlo,
)

__all__ = ['add_scenario_arguments', 'main_scenario', 'add_desired_density_arguments', 'main_desired_density',
           'plot_study']

_DEFAULTS = {'scenario1': (50, 'esc,fixed:2,fixed:4,fixed:6'), 'scenario2': (100, 'esc,fixed:3,fixed:4')}


def add_scenario_arguments(parser, scenario: str) -> None:
    """Arguments of ``sonar_eval scenario1`` / ``scenario2``."""
    scans, methods = _DEFAULTS[scenario]
    if scenario == 'scenario1':
        parser.add_argument('--lam', type=float, default=1.2, help='clutter rate lam of eq. 15 (paper: 1.2 and 0.8)')
    parser.add_argument('--tau0', type=float, default=3.0, help='initial ESC threshold (paper: 3)')
    parser.add_argument('--runs', type=int, default=100, help='Monte Carlo runs (paper: 500)')
    parser.add_argument('--scans', type=int, default=scans, help=f'scans per run (paper: {scans})')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--methods', default=methods,
                        help=f'comma list of esc (from --tau0), esc:T0 and fixed:T (default {methods})')
    parser.add_argument('--desired-density', type=float, default=PAPER_DESIRED_DENSITY[scenario],
                        help=f'rho_D [1/m^2] (default: the paper\'s {PAPER_DESIRED_DENSITY[scenario]:g})')
    parser.add_argument('--snr-db', type=float, default=8.0)
    parser.add_argument('--confirm', type=float, default=None,
                        help='the tracker\'s confirmation threshold T_c (default: the tracker\'s, 0.98)')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write the results here')
    parser.add_argument('--plot', type=Path, default=None, help='write a PNG in the style of the paper\'s figures')
    parser.set_defaults(scenario=scenario)


def main_scenario(args) -> int:
    """Run a scenario study; print a summary table; write JSON and plot."""
    try:
        methods = parse_methods(args.methods)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if args.runs < 1 or args.scans < 2 or args.jobs < 1:
        print('error: --runs, --jobs must be >= 1 and --scans >= 2', file=sys.stderr)
        return 2
    study = StudyConfig(scenario=args.scenario, scans=args.scans, lam=getattr(args, 'lam', 1.6), tau0=args.tau0,
                        desired_density=args.desired_density, snr_db=args.snr_db, methods=methods,
                        confirm=args.confirm)
    t0 = time.monotonic()
    try:
        with pool_from_args(args) as pool:
            runs = run_monte_carlo(run_once, study, args.runs, args.seed, progress=Progress(args.scenario, args.runs),
                                   pool=pool)
            where = pool.describe()
    except ClusterUnavailable as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    wall = time.monotonic() - t0
    result = {'scenario': args.scenario, 'runs': args.runs, 'scans': args.scans, 'seed': args.seed,
              'confirm': args.confirm, 'tau0': args.tau0,
              'desired_clutter_density': args.desired_density, 'wall_s': wall, 'jobs': args.jobs,
              'methods': summarise(study, runs)}
    if args.scenario == 'scenario1':
        result['lam'] = args.lam
    half = args.scans // 2
    print(f'{args.scenario}: {args.runs} runs x {args.scans} scans in {wall:.1f} s on {where}')
    print(f'{"method":10s}{"CTTR 2nd half":>15s}{"RMSE 2nd half":>15s}{"final tau":>11s}{"CFT rate":>10s}')
    for name, m in result['methods'].items():
        rmse = [v for v in m['rmse'][half:] if v is not None]
        print(f'{name:10s}{np.mean(m["cttr"][half:]):15.3f}{(np.mean(rmse) if rmse else math.nan):15.2f}'
              f'{m["threshold"][-1]:11.3f}{m["cft_rate"]:10.4f}')
    if args.json:
        write_json(args.json, result)
    if args.plot:
        write_plot(args.plot, plot_study, result)
    return 0


def plot_study(result: dict, path: Path) -> None:
    """CTTR, RMSE, threshold and density against scan, one line per method (Figures 5-19)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    scans = np.arange(1, result['scans'] + 1)
    for name, m in result['methods'].items():
        axes[0, 0].plot(scans, m['cttr'], label=name)
        axes[0, 1].plot(scans, [np.nan if v is None else v for v in m['rmse']], label=name)
        axes[1, 0].plot(scans, m['threshold'], label=name)
        axes[1, 1].semilogy(scans, np.maximum(m['clutter_density'], 1e-9), label=name)
    axes[1, 1].axhline(result['desired_clutter_density'], color='k', ls='--', label='rho_D')
    for ax, title in zip(axes.flat, ('confirmed true track rate', 'position RMSE [m]', 'detection threshold',
                                     'estimated clutter density [1/m^2]')):
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel('scan')
    lam = f', lam {result["lam"]:g}' if 'lam' in result else ''
    fig.suptitle(f'{result["scenario"]}{lam}: {result["runs"]} Monte Carlo runs')
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def add_desired_density_arguments(parser) -> None:
    """Arguments of ``sonar_eval desired-density``."""
    parser.add_argument('--snr-db', type=float, nargs='+', default=[8.0], help='one or more SNRs [dB]')
    parser.add_argument('--runs', type=int, default=100, help='Monte Carlo runs per (P_D, rho)')
    parser.add_argument('--scans', type=int, default=50)
    parser.add_argument('--models', default='cv,ccw,cw', help='tracker modes (cv = IPDA, as in Scenario 1)')
    parser.add_argument('--pd-step', type=float, default=0.01)
    parser.add_argument('--rho-min', type=float, default=1e-6)
    parser.add_argument('--rho-max', type=float, default=5e-4)
    parser.add_argument('--cft-target', type=float, default=0.005)
    parser.add_argument('--seed', type=int, default=0)
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write every candidate\'s figures here')
    parser.add_argument('--table', type=Path, default=None, help='write the desired-density table (YAML) here')


def main_desired_density(args) -> int:
    """Algorithm 1 for each SNR; print rho_D, write JSON and the YAML table."""
    if args.runs < 1 or not 0 < args.pd_step < 1 or not 0 < args.rho_min < args.rho_max:
        print('error: need --runs >= 1, 0 < --pd-step < 1 and 0 < --rho-min < --rho-max', file=sys.stderr)
        return 2
    t0 = time.monotonic()
    entries, details = [], []
    try:
        with pool_from_args(args) as pool:
            for snr in args.snr_db:
                entry = _desired_density(args, snr, pool)
                if entry is None:
                    return 1
                entries.append(entry[0])
                details.append(entry[1])
    except ClusterUnavailable as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    wall = time.monotonic() - t0
    command = 'sonar_eval desired-density ' + ' '.join(shlex.quote(a) for a in sys.argv[2:]) if len(sys.argv) > 2 \
        else 'sonar_eval desired-density'
    if args.json:
        write_json(args.json, {'runs': args.runs, 'scans': args.scans, 'models': args.models, 'wall_s': wall,
                               'snr': details})
    if args.table:
        header = (f'# Desired clutter density rho_D against SNR (ESC paper Algorithm 1), made by:\n'
                  f'#   {command}\n# on {datetime.date.today().isoformat()}, {wall:.0f} s; tracker modes '
                  f'{args.models}. active_detector interpolates log(rho_D) in SNR when\n'
                  f'# esc.desired_clutter_density is 0.\n')
        args.table.parent.mkdir(parents=True, exist_ok=True)
        args.table.write_text(header + yaml.safe_dump({'models': args.models, 'entries': entries}, sort_keys=False))
        print(f'wrote {args.table}')
    return 0


def _desired_density(args, snr: float, pool) -> tuple[dict, dict] | None:
    """Algorithm 1 at one SNR: the table entry and the details, or None (reason printed)."""
    cfg = algorithm1.Algorithm1Config(snr_db=snr, models=args.models, scans=args.scans, pd_step=args.pd_step,
                                      rho_min=args.rho_min, rho_max=args.rho_max, cft_target=args.cft_target)
    cands = algorithm1.candidates(cfg)
    if not cands:
        print(f'SNR {snr:g} dB: no P_D gives a density inside ({args.rho_min:g}, {args.rho_max:g})', file=sys.stderr)
        return None
    progress = Progress(f'SNR {snr:g} dB', len(cands) * args.runs)
    results = {}
    for pd, rho in cands:
        # The same seeds for every candidate (common random numbers): the candidates' nCTT differ
        # by their (P_D, rho), not by independent noise.
        results[(pd, rho)] = run_monte_carlo(algorithm1.run_candidate, (cfg, pd, rho), args.runs, args.seed,
                                             progress=progress, pool=pool)
    best = algorithm1.choose(cfg, results)
    print(f'SNR {snr:g} dB: rho_D = {best["desired_clutter_density"]:.3g} /m^2 ({best["method"]}; raw argmax '
          f'{best["raw_argmax_density"]:.3g}) at P_D {best["pd"]:.2f}, T_c {best["t_c"]}, nCTT {best["n_ctt"]} '
          f'of {args.runs * args.scans}')
    return ({'snr_db': snr, 'desired_clutter_density': float(best['desired_clutter_density']),
             'pd': best['pd'], 't_c': best['t_c']}, {'snr_db': snr, 'v_rc': cfg.v_rc, **best})


def add_table_arguments(parser) -> None:
    """Arguments of ``sonar_eval esc-table``."""
    from sonar_tracking.studies.evidence import add_seed_arguments
    add_seed_arguments(parser, calibration='101', evaluation='201,202', runs=250, calibration_runs=200)
    parser.add_argument('--scans', type=int, default=0, help='scans per run, 0 = the paper\'s (50, 100)')
    parser.add_argument('--cft-target', type=float, default=0.005,
                        help='rate of CFT scans (Table 1) that sets T_c per method (default 0.005)')
    parser.add_argument('--max-steps', type=int, default=3,
                        help='grid steps T_c may move from the sweep\'s choice when checked inside the run (default 3)')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write the results here')


def main_table(args) -> int:
    """Run the ESC comparison at the paper's operating point, out of sample; print the docs/results tables."""
    from sonar_tracking.studies.esc_table import TUNED_ON, format_table, run_table
    split = seed_split_or_none(args, TUNED_ON)
    if split is None:
        return 2
    if args.jobs < 1 or (args.scans and args.scans < 4) or not 0 < args.cft_target < 1 or args.max_steps < 0:
        print('error: need --jobs >= 1, --scans 0 or >= 4, 0 < --cft-target < 1 and --max-steps >= 0', file=sys.stderr)
        return 2
    return table_command('esc-table', args, lambda pool: run_table(split, args.runs, args.calibration_runs, pool,
                                                                    args.scans or None, args.cft_target,
                                                                    max_steps=args.max_steps), format_table)

"""``sonar_eval``: offline evaluation and tools of sonar_tracking.

Subcommands:
  bench            time the core and adapters (table + JSON), with ratios against baselines
  track            IMM-IPDA on recorded detections: CSV in, CSV of tracks out
  scenario1        ESC paper Scenario 1 (§5.1): ESC against fixed thresholds, Monte Carlo
  scenario2        ESC paper Scenario 2 (§5.2): manoeuvring target, two clutter regions
  desired-density  ESC paper Algorithm 1 (§4): the desired clutter density for an SNR
  esc-table        ESC against fixed thresholds at the paper's operating point, out of sample: T_c per
                   method for a CFT rate of 0.005 chosen on calibration seeds, every tracker run at it on
                   two evaluation seed sets, corrected paired intervals: the docs/results table
  select-features  FLS paper §3: GRNN feature selection by SFS or SBS on simulated tank regions
  fls              FLS paper §5: GPF, SIR and EKF tracks on Table 5 situations or the sea trial
  fls-table        FLS paper: the crossing situations 8-11 by fusion, ranked on capped CLE, each method at
                   its confirmation chosen on calibration seeds, corrected paired intervals on two
                   evaluation seed sets: the docs/results table
  structure        confirmed tracks on static structure (walls, seabed, piles, ringdown), with and
                   without rejection, next to the structure-free scenes
  jipda            IMM-JIPDA against IMM-IPDA on two crossing or parallel targets, in and out of the
                   trackers' model (SCMDE clutter, wrong P_D, manoeuvres, unresolved targets), each at its
                   T_c chosen on calibration seeds, corrected paired intervals: the docs/results table
  imaging          imaging sonars on the simulated Oculus-class head: P_D against false detections per CFAR
                   variant, ESC under a change of clutter shape, the static empty scene, the diver (CTTR,
                   false tracks per hour), the crossing school (JIPDA against IPDA), out of sample
  soak             start-work-stop cycles of every node under CPU load: crashes, hangs, exit codes

The Monte Carlo subcommands run over --jobs processes or a Dask cluster (--cluster).
"""
from __future__ import annotations

import argparse
import sys

__all__ = ['main', 'build_parser']


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand (their modules load only when run)."""
    from sonar_tracking.cli import (
        bench,
        esc_eval,
        fls_eval,
        imaging_eval,
        jipda_eval,
        select_features,
        soak,
        structure_eval,
        track_csv,
    )
    parser = argparse.ArgumentParser(prog='sonar_eval', description=__doc__.split('\n\n')[0].replace('``', ''),
                                     epilog=__doc__.split('\n\n', 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True
    p = sub.add_parser('bench', help='run benchmarks: median and spread per case, ratios to baselines')
    bench.add_arguments(p)
    p.set_defaults(handler=bench.main_args)
    p = sub.add_parser('track', help='IMM-IPDA tracks from a CSV of detections')
    track_csv.add_arguments(p)
    p.set_defaults(handler=track_csv.main_args)
    for scenario in ('scenario1', 'scenario2'):
        p = sub.add_parser(scenario, help=f'ESC paper {scenario}: CTTR, RMSE, threshold, density by method')
        esc_eval.add_scenario_arguments(p, scenario)
        p.set_defaults(handler=esc_eval.main_scenario)
    p = sub.add_parser('desired-density', help='ESC paper Algorithm 1: rho_D for each SNR, and the table')
    esc_eval.add_desired_density_arguments(p)
    p.set_defaults(handler=esc_eval.main_desired_density)
    p = sub.add_parser('esc-table', help='ESC paper: every method at its T_c for a CFT rate of 0.005 chosen on '
                       'calibration seeds, paired differences ESC - fixed on two evaluation seed sets (the '
                       'docs/results table)')
    esc_eval.add_table_arguments(p)
    p.set_defaults(handler=esc_eval.main_table)
    p = sub.add_parser('select-features', help='FLS paper §3: GRNN feature selection by SFS or SBS on simulated '
                       'tank regions')
    select_features.add_arguments(p)
    p.set_defaults(handler=select_features.main_args)
    p = sub.add_parser('fls', help='FLS paper §5: GPF (af, mf, wf), SIR and EKF tracks on Table 5 situations or the '
                       'sea-trial preset, CLE by method')
    fls_eval.add_arguments(p)
    p.set_defaults(handler=fls_eval.main_args)
    p = sub.add_parser('fls-table', help='FLS paper: the crossing situations 8-11, af (crossing switch), af18 '
                       '(eq. 18 alone), mf, wf ranked on capped CLE and paired on two evaluation seed sets (the '
                       'docs/results table)')
    fls_eval.add_table_arguments(p)
    p.set_defaults(handler=fls_eval.main_table)
    p = sub.add_parser('structure', help='confirmed tracks on static structure of the structured scenes, with and '
                       'without rejection, and the targets against the structure-free twin')
    structure_eval.add_arguments(p)
    p.set_defaults(handler=structure_eval.main_args)
    p = sub.add_parser('jipda', help='IMM-JIPDA against IMM-IPDA on crossing and parallel targets, in and out of '
                       'the trackers\' model, paired on two evaluation seed sets (the docs/results table)')
    jipda_eval.add_arguments(p)
    p.set_defaults(handler=jipda_eval.main_args)
    p = sub.add_parser('imaging', help='imaging sonars: CFAR variants, ESC under a change of clutter shape, the '
                       'static scene, the diver and the crossing school, out of sample (the docs/results table)')
    imaging_eval.add_arguments(p)
    p.set_defaults(handler=imaging_eval.main_args)
    p = sub.add_parser('soak', help='start, work and stop every node many times under CPU load: crashes, hangs '
                       'and exit statuses at SIGINT')
    soak.add_arguments(p)
    p.set_defaults(handler=soak.main_args)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sonar_eval`` executable."""
    from sonar_tracking import process
    process.prepare()   # fresh kernel caches; large numpy temporaries stay on the heap
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())

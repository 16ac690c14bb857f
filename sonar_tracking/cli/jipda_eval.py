"""``sonar_eval jipda``: IMM-JIPDA against IMM-IPDA in and out of the trackers' model, out of sample
(the docs/results table; :mod:`sonar_tracking.studies.jipda_table`)."""
from __future__ import annotations

import sys
from pathlib import Path

from sonar_tracking.cli._output import comma_choices, seed_split_or_none, table_command
from sonar_tracking.studies.montecarlo import add_pool_arguments

__all__ = ['add_arguments', 'main_args']


def add_arguments(parser) -> None:
    """Arguments of ``sonar_eval jipda``."""
    from sonar_tracking.studies.evidence import add_seed_arguments
    from sonar_tracking.studies.jipda_study import CONDITIONS
    add_seed_arguments(parser, calibration='301', evaluation='401,402', runs=400, calibration_runs=150)
    parser.add_argument('--scans', type=int, default=0, help='scans per run, 0 = the study\'s (100)')
    parser.add_argument('--geometry', choices=('crossing', 'parallel', 'both'), default='both')
    parser.add_argument('--conditions', default=','.join(CONDITIONS),
                        help=f'comma list of {",".join(CONDITIONS)} (default all): where the trackers\' model is '
                        'wrong (matched: nowhere)')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write the results (and every run\'s figures) here')


def main_args(args) -> int:
    """Run the study; print the docs/results tables."""
    from sonar_tracking.studies.jipda_study import CELLS, CONDITIONS
    from sonar_tracking.studies.jipda_table import TUNED_ON, format_table, run_table
    split = seed_split_or_none(args, TUNED_ON)
    conditions = comma_choices(args.conditions, CONDITIONS, '--conditions') if split else None
    if split is None or conditions is None:
        return 2
    if args.jobs < 1 or (args.scans and args.scans < 2):
        print('error: need --jobs >= 1 and --scans 0 or >= 2', file=sys.stderr)
        return 2
    cells = tuple((g, c) for g, c in CELLS if c in conditions and args.geometry in ('both', g))
    if not cells:
        print('error: no cell left: parallel targets are never unresolved (use --geometry crossing or both)',
              file=sys.stderr)
        return 2
    return table_command('jipda', args, lambda pool: run_table(split, args.runs, args.calibration_runs, pool,
                                                               args.scans or None, cells), format_table)

"""``sonar_eval jipda``: IMM-JIPDA against IMM-IPDA on crossing and parallel targets (the docs/results table)."""
from __future__ import annotations

import sys
from pathlib import Path

from sonar_tracking.cli._output import table_command
from sonar_tracking.studies.montecarlo import add_pool_arguments

__all__ = ['add_arguments', 'main_args']


def add_arguments(parser) -> None:
    """Arguments of ``sonar_eval jipda``."""
    parser.add_argument('--runs', type=int, default=500, help='Monte Carlo runs per geometry')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--scans', type=int, default=0, help='scans per run, 0 = the study\'s (100)')
    parser.add_argument('--geometry', choices=('crossing', 'parallel', 'both'), default='both')
    parser.add_argument('--unresolved', action='store_true',
                        help='two targets detected within one resolution cell give one merged detection')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write the results (and every run\'s figures) here')


def main_args(args) -> int:
    """Run the study (:mod:`sonar_tracking.studies.jipda_study`); print the docs/results table."""
    from sonar_tracking.studies.jipda_study import GEOMETRIES, format_table, run_study
    if args.runs < 2 or args.jobs < 1 or (args.scans and args.scans < 2):
        print('error: need --runs >= 2, --jobs >= 1 and --scans 0 or >= 2', file=sys.stderr)
        return 2
    geometries = GEOMETRIES if args.geometry == 'both' else (args.geometry,)
    return table_command('jipda', args, lambda pool: run_study(args.runs, args.seed, pool, args.scans or None,
                                                               geometries, unresolved=args.unresolved),
                         format_table)

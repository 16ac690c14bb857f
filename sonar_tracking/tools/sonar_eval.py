"""``sonar_eval``: offline evaluation and tools of sonar_tracking.

Subcommands:
  bench   time the core and adapters (table + JSON), with ratios against baselines
"""
from __future__ import annotations

import argparse
import sys

from . import bench

__all__ = ['main', 'build_parser']


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(prog='sonar_eval', description=__doc__.split('\n\n')[0].strip('`'),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True
    p = sub.add_parser('bench', help='run benchmarks: median and spread per case, ratios to baselines')
    bench.add_arguments(p)
    p.set_defaults(handler=bench.main_args)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sonar_eval`` executable."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())

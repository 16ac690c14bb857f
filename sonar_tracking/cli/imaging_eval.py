"""``sonar_eval imaging``: the imaging-sonar front end and trackers on a simulated head (the Oculus
class unless ``--sensor`` names another), out of sample (:mod:`sonar_tracking.studies.imaging_table`):
detection against false detections per CFAR variant, ESC under a change of clutter shape, the static
empty scene, the diver, the crossing school (JIPDA against IPDA)."""
from __future__ import annotations

import sys
from pathlib import Path

from sonar_tracking.cli._output import comma_choices, seed_split_or_none, table_command
from sonar_tracking.studies.montecarlo import add_pool_arguments

__all__ = ['add_arguments', 'main_args']


def add_arguments(parser) -> None:
    """Arguments of ``sonar_eval imaging``."""
    from sonar_tracking.sim.presets import IMAGING_PRESETS
    from sonar_tracking.studies.evidence import add_seed_arguments
    from sonar_tracking.studies.imaging_table import PARTS, REDUCED, SENSOR, STATIC_FRAMES
    add_seed_arguments(parser, calibration='501', evaluation='601,602', runs=45, calibration_runs=6)
    parser.add_argument('--parts', default=','.join(PARTS), help=f'comma list of {",".join(PARTS)} (default all)')
    parser.add_argument('--roc-runs', type=int, default=100, help='runs per CFAR variant and design P_fa')
    parser.add_argument('--esc-runs', type=int, default=20, help='runs per evaluation seed set of the ESC part')
    parser.add_argument('--scale', type=int, default=REDUCED, help='frame reduction of roc, diver and school: every '
                        'N-th beam and bin (1 = full size)')
    parser.add_argument('--static-frames', type=int, default=STATIC_FRAMES, help='frames of the static scene')
    parser.add_argument('--static-scale', type=int, default=1, help='frame reduction of the static scene')
    parser.add_argument('--sensor', default=SENSOR, choices=IMAGING_PRESETS,
                        help=f'simulated head, with its parameter file (default {SENSOR}); the esc and school parts '
                        f'are set in its cells and run on {SENSOR} only')
    parser.add_argument('--frames', type=int, default=0, help='frames per diver and school run (0: the scenario)')
    add_pool_arguments(parser)
    parser.add_argument('--json', type=Path, default=None, help='write the results (and every run\'s figures) here')


def main_args(args) -> int:
    """Run the study; print the docs/results tables."""
    from sonar_tracking.studies.imaging_table import PARTS, SENSOR, TUNED_ON, Sizes, format_table, run_table
    split = seed_split_or_none(args, TUNED_ON)
    parts = comma_choices(args.parts, PARTS, '--parts') if split else None
    if split is None or parts is None:
        return 2
    own = [p for p in parts if p in ('esc', 'school')]
    if args.sensor != SENSOR and own:
        print(f'error: --parts {",".join(own)} are set in the cells of {SENSOR} (the ESC window, the fish); '
              f'with --sensor {args.sensor} choose from roc,static,diver', file=sys.stderr)
        return 2
    counts = (args.runs, args.calibration_runs, args.roc_runs, args.esc_runs, args.scale, args.static_scale,
              args.jobs)
    if min(counts) < 1 or args.static_frames < 2 or args.frames < 0:
        print('error: runs, scales and --jobs must be >= 1, --static-frames >= 2, --frames >= 0', file=sys.stderr)
        return 2
    sizes = Sizes(args.runs, args.calibration_runs, args.roc_runs, args.esc_runs, args.static_frames, args.frames,
                  args.frames, args.scale, args.static_scale, sensor=args.sensor)
    return table_command('imaging', args, lambda pool: run_table(split, sizes, parts, pool), format_table)

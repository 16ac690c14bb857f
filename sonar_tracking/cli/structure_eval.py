"""``sonar_eval structure``: confirmed tracks on static structure, with and without rejection.

For each scenario (default: the tank and harbour ``structure_only`` scenes and one structured scene
with targets per pipeline), the frames run through the sensor's front end and tracker
(:func:`~sonar_tracking.studies.structure_study.run_structure_study`) three ways: with
static-structure rejection (:data:`~sonar_tracking.studies.structure_study.STRUCTURE_REJECTION`),
without it, and, for a ``*_structured`` scene, its structure-free twin with rejection, so the
targets' CTTR and CLE can be compared. Same seed, same scene and noise in all three. A scene
without targets runs ``--frames`` frames in one run; a scene with targets runs for its own duration
(its targets' paths) over seeds ``seed, seed + 1, ...`` until ``--frames`` frames are reached.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

__all__ = ['add_arguments', 'main_args', 'DEFAULT_SCENARIOS']

NO_TARGETS = ('structure_only', 'clutter')
DEFAULT_SCENARIOS = ('structure_only:seaking675', 'fls8_structured', 'structure_only:harbour', 'scenario2_structured')


def add_arguments(parser: Any) -> None:
    """Arguments of ``sonar_eval structure``."""
    parser.add_argument('--scenarios', nargs='+', default=list(DEFAULT_SCENARIOS), metavar='NAME[:PRESET]',
                        help='structured scenarios, each optionally with its sensor preset (default: '
                             + ' '.join(DEFAULT_SCENARIOS) + ')')
    parser.add_argument('--frames', type=int, default=100, help='SeaKing sweeps or harbour scans per row (100)')
    parser.add_argument('--seed', type=int, default=1, help='seed of the scene and its noise (1)')
    parser.add_argument('--json', type=Path, help='write the counts as JSON')


def _row(name: str, rejection: str, c) -> dict:
    return {'scenario': name, 'rejection': rejection, 'frames': c.frames, 'confirmed_tracks': c.confirmed_tracks,
            'on_structure': c.on_structure, 'elsewhere': c.elsewhere, 'on_target': c.on_target,
            'cttr': None if math.isnan(c.cttr) else c.cttr, 'cle': None if math.isnan(c.cle) else c.cle}


def main_args(args: Any) -> int:
    """Run ``sonar_eval structure``; returns the exit status (1 when a rejecting run kept a track on
    structure)."""
    from sonar_tracking.cli._output import write_json
    from sonar_tracking.sim import SimConfig
    from sonar_tracking.studies.structure_study import STRUCTURE_REJECTION, combine, plain_twin, run_structure_study
    if args.frames < 1:
        print('error: --frames must be >= 1', file=sys.stderr)
        return 2
    rows = []
    for item in args.scenarios:
        name, _, preset = item.partition(':')
        try:
            harbour = SimConfig.for_scenario(name, preset).is_harbour
        except ValueError as exc:
            print(f'error: {item}: {exc}', file=sys.stderr)
            return 2
        on = STRUCTURE_REJECTION['harbour' if harbour else 'seaking']
        runs = [(name, 'on', on), (name, 'off', {})]
        twin = plain_twin(name)
        if twin:
            runs.append((twin, 'on', on))
        for scenario, rejection, front_end in runs:
            print(f'  {scenario}{":" + preset if preset else ""}, rejection {rejection} ...', file=sys.stderr)
            cfg = SimConfig.for_scenario(scenario, preset)
            period = cfg.harbour.scan_period if harbour else cfg.seaking.sweep_time
            own = max(1, int(cfg.duration / period)) if scenario not in NO_TARGETS else args.frames
            counts, k = [], 0
            while sum(c.frames for c in counts) < args.frames:
                counts.append(run_structure_study(scenario, args.seed + k, min(own, args.frames), preset,
                                                  front_end=front_end))
                k += 1
            rows.append(_row(scenario + (f':{preset}' if preset else ''), rejection, combine(counts)))
    fmt = '{:<30} {:>9} {:>6} {:>9} {:>12} {:>9} {:>6} {:>7}'
    print(fmt.format('scenario', 'rejection', 'frames', 'confirmed', 'on structure', 'elsewhere', 'CTTR', 'CLE'))
    for r in rows:
        print(fmt.format(r['scenario'], r['rejection'], r['frames'], r['confirmed_tracks'], r['on_structure'],
                         r['elsewhere'], '-' if r['cttr'] is None else f'{r["cttr"]:.3f}',
                         '-' if r['cle'] is None else f'{r["cle"]:.2f}'))
    if args.json:
        write_json(args.json, {'seed': args.seed, 'frames': args.frames, 'rows': rows})
    kept = [r for r in rows if r['rejection'] == 'on' and r['on_structure']]
    return 1 if kept else 0

"""``sonar_eval select-features``: GRNN wrapper feature selection by SFS or SBS (FLS paper §3.2-§3.4).

The command line of :mod:`sonar_tracking.studies.feature_selection` (the study: simulated tank
situations, regions labelled by shape, SFS or SBS with the GRNN, error against the number of
features and the most frequent first five against the paper's): arguments, the summary printed,
the JSON and the plot (Figures 6 and 9 style). Runs spread over ``--jobs`` processes or a Dask
cluster (``--cluster``); the results depend only on ``--seed``.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from sonar_tracking.cli._output import write_json, write_plot

__all__ = ['add_arguments', 'main_args', 'plot']


def add_arguments(parser: Any) -> None:
    """Arguments of ``sonar_eval select-features``."""
    from sonar_tracking.studies.montecarlo import add_pool_arguments
    parser.add_argument('--method', choices=('sfs', 'sbs'), default='sfs',
                        help='sequential forward (Table 4) or backward (Table 3) selection (default sfs)')
    parser.add_argument('--runs', type=int, default=5, help='independent runs, each on freshly simulated frames '
                        '(default 5)')
    parser.add_argument('--json', type=Path, required=True, help='write the results to this JSON file')
    parser.add_argument('--plot', type=Path, default=None, help='also draw error vs number of features and '
                        'feature frequencies to this PNG')
    parser.add_argument('--seed', type=int, default=0, help='seed of the first run; run r uses seed + r (default 0)')
    parser.add_argument('--situations', type=str, default='1-14',
                        help='FLS Table 5 situations to simulate, e.g. "1-4,7" (default 1-14)')
    parser.add_argument('--sweeps', type=int, default=0,
                        help='sweeps used per situation and run, 0 = the whole situation (default 0)')
    parser.add_argument('--preset', choices=('seaking675', 'seaking325'), default='seaking675',
                        help='SeaKing model (default seaking675)')
    parser.add_argument('--sigma', type=float, default=0.1,
                        help='GRNN smoothing factor, relative to the RMS distance of rank-scaled features '
                        '(default 0.1)')
    parser.add_argument('--seed-db', type=float, default=4.0,
                        help='segmentation seed threshold for the training regions, dB (default 4.0; the node '
                        'uses 5.5)')
    parser.add_argument('--max-clutter-ratio', type=float, default=2.0,
                        help='keep at most this many clutter regions per region of the largest target class '
                        '(default 2)')
    add_pool_arguments(parser)


def _parse_situations(text: str) -> tuple[int, ...]:
    out: set[int] = set()
    for part in text.split(','):
        part = part.strip()
        if not part:
            continue
        lo, _, hi = part.partition('-')
        a, b = int(lo), int(hi or lo)
        if not (1 <= a <= b <= 14):
            raise ValueError(f'situation range {part!r} is outside 1-14')
        out.update(range(a, b + 1))
    if not out:
        raise ValueError('no situation given')
    return tuple(sorted(out))


def plot(result: dict, path: Path) -> None:
    """Error against the number of features (Figure 6 style) and top-five frequencies (Figure 9)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    s = result['summary']
    k = np.arange(1, len(s['mean_test_error']) + 1)
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    mean, std = np.array(s['mean_test_error']), np.array(s['std_test_error'])
    a.plot(k, mean, 'o-', label=f'test ({result["runs"]} runs, mean)')
    a.fill_between(k, mean - std, mean + std, alpha=0.25)
    a.plot(k, s['mean_validation_error'], '.--', label='validation (selection criterion)')
    a.axhline(s['paper_test_error'], color='C3', ls=':', label='paper features 20, 17, 3, 6, 24')
    a.axhline(s['chance_error'], color='gray', ls=':', lw=1, label='chance')
    a.set_xlabel('number of features')
    a.set_ylabel('balanced classification error')
    a.set_title(f'GRNN + {result["method"].upper()}')
    a.legend(fontsize=8)
    counts = s['top5_counts']
    feats = np.arange(1, 31)
    colors = ['C3' if f in s['paper_features'] else 'C0' for f in feats]
    b.bar(feats, [counts[str(f)] for f in feats], color=colors)
    b.set_xlabel('feature (Table 2 number; red = the paper\'s five)')
    b.set_ylabel('runs with the feature among the first five')
    b.set_xticks(feats)
    b.tick_params(axis='x', labelsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main_args(args: Any) -> int:
    """Run ``sonar_eval select-features`` with parsed arguments; returns the exit status."""
    if args.runs < 1:
        print('error: --runs must be >= 1', file=sys.stderr)
        return 2
    if not (args.sigma > 0 and math.isfinite(args.sigma)):
        print('error: --sigma must be a positive number', file=sys.stderr)
        return 2
    if args.sweeps < 0:
        print('error: --sweeps must be >= 0', file=sys.stderr)
        return 2
    try:
        situations = _parse_situations(args.situations)
    except ValueError as exc:
        print(f'error: --situations: {exc}', file=sys.stderr)
        return 2
    if args.jobs < 1:
        print('error: --jobs must be >= 1', file=sys.stderr)
        return 2
    from sonar_tracking.studies.feature_selection import SelectionStudy, run_selection
    from sonar_tracking.studies.montecarlo import ClusterUnavailable, Progress, pool_from_args
    study = SelectionStudy(args.method, situations, args.sweeps, args.preset, args.sigma, args.seed_db,
                           args.max_clutter_ratio)
    try:
        with pool_from_args(args) as pool:
            result = run_selection(study, args.runs, args.seed, pool, Progress(f'select-features {args.method}',
                                                                             args.runs))
    except ClusterUnavailable as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except RuntimeError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    for r, p in enumerate(result['per_run']):
        e = p['test_error']
        print(f'  run {r + 1}/{args.runs}: best {p["best_k"]} features {p["best_subset"]}, test error '
              f'{e[p["best_k"] - 1]:.3f}; first five {p["top5"]} {e[4]:.3f}; paper {p["paper_test_error"]:.3f}',
              file=sys.stderr)
    s = result['summary']
    print(f'{result["method"].upper()}, {result["runs"]} runs, classes {s["class_counts"]}')
    print(f'  least mean test error {s["best_mean_test_error"]:.3f} with {s["best_k"]} features '
          f'(chance {s["chance_error"]:.3f})')
    print(f'  five features: {s["five_feature_test_error"]:.3f}; all 30: {s["all_features_test_error"]:.3f}')
    print(f'  most frequent first five: {s["consensus_top5"]}; paper {s["paper_features"]}: '
          f'{s["paper_test_error"]:.3f}')
    write_json(args.json, result)
    if args.plot:
        write_plot(args.plot, plot, result)
    return 0

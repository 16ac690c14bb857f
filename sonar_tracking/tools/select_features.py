"""``sonar_eval select-features``: GRNN wrapper feature selection by SFS or SBS (FLS paper §3.2-§3.4).

Each run simulates the FLS paper's tank situations (Table 5: the pontoon, cube, triangular prism,
reflector and sphere of §3.4, alone, side by side and crossing) with its own seed, processes the
sweeps with the ``fls_features`` pipeline and labels every region with the shape of the target it
lies on, or ``clutter``. The frames are split three ways (half for training, a quarter for
validation, a quarter for testing, whole frames each so neighbouring regions do not leak between
sets). SFS or SBS (Tables 3-4) searches the 30 features of Table 2 with the GRNN of eq. (4):
trained on the training regions, judged by its balanced error on the validation regions. Each
subset along the path is then retrained on training + validation and its error measured on the
test regions: the error against the number of features (the paper's Figure 6). The runs are
summarised as in Figures 7-9 and Table 7: the mean and spread of the error per subset size, how
often each feature is among the first five selected, and the five most frequent against the
paper's (20, 17, 3, 6, 24).

The regions are segmented with a seed threshold ``--seed-db`` below the node's default, so that
enough clutter regions exist to learn the clutter class (at the default almost none are found).
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ._output import write_json, write_plot

__all__ = ['add_arguments', 'main_args', 'run_selection']

SITUATIONS = tuple(range(1, 15))


def add_arguments(parser: Any) -> None:
    """Arguments of ``sonar_eval select-features``."""
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


def _dataset(seed: int, situations: tuple[int, ...], sweeps: int, preset: str, seed_db: float):
    from sonar_tracking.core.fls import FlsConfig
    from sonar_tracking.core.fls.evaluation import region_dataset, simulate_frames
    config = FlsConfig.from_flat({'segment.seed_db': seed_db, 'segment.grow_db': min(3.0, seed_db)})
    frames = []
    for n in situations:
        frames += list(simulate_frames(f'fls{n}', 1000 * seed + n, config, preset=preset,
                                       max_frames=sweeps or None))
    return region_dataset(frames), len(frames)


def _split(ds, rng: np.random.Generator, max_clutter_ratio: float):
    """Train / validation / test by whole frames (1/2, 1/4, 1/4), clutter capped."""
    frames = np.unique(ds.frame)
    part = rng.permutation(frames.size) % 4  # 0, 1 train; 2 validation; 3 test
    which = np.zeros(ds.frame.max() + 1, np.int64)
    which[frames] = part
    keep = np.ones(len(ds), bool)
    counts = ds.counts()
    targets = [v for k, v in counts.items() if k != 'clutter']
    if 'clutter' in counts and targets:
        cap = int(max_clutter_ratio * max(targets))
        clutter = np.flatnonzero(ds.labels == 'clutter')
        if clutter.size > cap:
            keep[rng.choice(clutter, clutter.size - cap, replace=False)] = False
    sets = which[ds.frame]
    return (ds.subset(keep & (sets <= 1)), ds.subset(keep & (sets == 2)), ds.subset(keep & (sets == 3)),
            ds.subset(keep))


def _test_error(train, test, subset: tuple[int, ...], sigma: float) -> float:
    from sonar_tracking.core.fls.grnn import GRNN, balanced_error
    cols = [f - 1 for f in subset]
    model = GRNN(sigma).fit(train.features[:, cols], train.labels)
    return balanced_error(test.labels, model.predict(test.features[:, cols]))


def _confusion(train, test, subset: tuple[int, ...], sigma: float, classes: list[str]) -> list[list[int]]:
    from sonar_tracking.core.fls.grnn import GRNN
    cols = [f - 1 for f in subset]
    pred = GRNN(sigma).fit(train.features[:, cols], train.labels).predict(test.features[:, cols])
    return [[int(np.sum((test.labels == a) & (pred == b))) for b in classes] for a in classes]


def run_selection(method: str, runs: int, seed: int = 0, situations: tuple[int, ...] = SITUATIONS, sweeps: int = 0,
                  preset: str = 'seaking675', sigma: float = 0.1, seed_db: float = 4.0,
                  max_clutter_ratio: float = 2.0, progress=None) -> dict:
    """Run the selection ``runs`` times; returns the JSON-ready result (see module docstring)."""
    from sonar_tracking.core.fls import PAPER_FEATURES
    from sonar_tracking.core.fls.evaluation import RegionDataset
    from sonar_tracking.core.fls.selection import GrnnWrapper, sbs, sfs
    t0 = time.perf_counter()
    per_run, totals = [], {}
    n_features = 30
    all_features = tuple(range(1, n_features + 1))
    for r in range(runs):
        run_seed = seed + r
        ds, n_frames = _dataset(run_seed, situations, sweeps, preset, seed_db)
        train, val, test, used = _split(ds, np.random.default_rng(run_seed), max_clutter_ratio)
        if min(len(train), len(val), len(test)) == 0 or len(np.unique(train.labels)) < 2:
            raise RuntimeError(f'run {r}: too few labelled regions ({ds.counts()}); simulate more sweeps')
        for k, v in used.counts().items():
            totals[k] = totals.get(k, 0) + v
        wrapper = GrnnWrapper(train.features, train.labels, val.features, val.labels, sigma=sigma)
        search = sfs if method == 'sfs' else sbs
        path = search(wrapper, all_features)
        both = RegionDataset(np.concatenate([train.features, val.features]),
                             np.concatenate([train.labels, val.labels]), np.concatenate([train.frame, val.frame]))
        test_err = [_test_error(both, test, s, sigma) for s in path.subsets]
        best_k = int(np.argmin(path.errors)) + 1
        classes = sorted(used.counts())
        per_run.append({
            'seed': run_seed, 'frames': n_frames, 'regions': {'train': len(train), 'validation': len(val),
                                                              'test': len(test)},
            'class_counts': used.counts(), 'order': path.order,
            'subsets': [list(s) for s in path.subsets],
            'validation_error': path.errors, 'test_error': test_err,
            'best_k': best_k, 'best_subset': list(path.subset_of(best_k)),
            'best_test_error': test_err[best_k - 1],
            'top5': list(path.order[:5]), 'top5_test_error': test_err[4] if len(test_err) >= 5 else math.nan,
            'paper_test_error': _test_error(both, test, PAPER_FEATURES, sigma),
            'all_test_error': test_err[-1],
            'classes': classes,
            'confusion_top5': _confusion(both, test, path.subset_of(5), sigma, classes),
            'evaluations': wrapper.evaluations,
        })
        if progress:
            progress(f'run {r + 1}/{runs}: best {best_k} features {list(path.subset_of(best_k))}, '
                     f'test error {test_err[best_k - 1]:.3f}; first five {path.order[:5]} '
                     f'{test_err[4]:.3f}; paper {per_run[-1]["paper_test_error"]:.3f}')
    test = np.array([p['test_error'] for p in per_run])
    val = np.array([p['validation_error'] for p in per_run])
    counts = {f: 0 for f in all_features}
    for p in per_run:
        for f in p['top5']:
            counts[f] += 1
    consensus = sorted(all_features, key=lambda f: (-counts[f], f))[:5]
    mean_test = test.mean(axis=0)
    summary = {
        'mean_test_error': mean_test.tolist(), 'std_test_error': test.std(axis=0).tolist(),
        'mean_validation_error': val.mean(axis=0).tolist(),
        'best_k': int(np.argmin(mean_test)) + 1, 'best_mean_test_error': float(mean_test.min()),
        'top5_counts': {str(f): c for f, c in counts.items()},
        'consensus_top5': consensus,
        'paper_features': list(PAPER_FEATURES),
        'paper_test_error': float(np.mean([p['paper_test_error'] for p in per_run])),
        'five_feature_test_error': float(mean_test[4]),
        'all_features_test_error': float(mean_test[-1]),
        'chance_error': 1.0 - 1.0 / max(1, len(totals)),
        'class_counts': totals,
    }
    return {'method': method, 'runs': runs, 'seed': seed, 'situations': list(situations), 'preset': preset,
            'sigma': sigma, 'seed_db': seed_db, 'per_run': per_run, 'summary': summary,
            'wall_s': time.perf_counter() - t0}


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
    try:
        result = run_selection(args.method, args.runs, args.seed, situations, args.sweeps, args.preset, args.sigma,
                               args.seed_db, args.max_clutter_ratio,
                               progress=lambda m: print(f'  {m}', file=sys.stderr))
    except RuntimeError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
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

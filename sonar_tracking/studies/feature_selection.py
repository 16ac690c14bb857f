"""GRNN wrapper feature selection by SFS or SBS (FLS paper §3.2-§3.4), as a Monte Carlo study.

Each run simulates the FLS paper's tank situations (Table 5: the pontoon, cube, triangular prism,
reflector and sphere of §3.4, alone, side by side and crossing) with its own seed, processes the
sweeps with the ``fls_features`` pipeline and labels every region with the shape of the target it
lies on, or ``clutter`` (:func:`~.fls_segmentation.region_dataset`). The frames are split three
ways (half for training, a quarter for validation, a quarter for testing, whole frames each so
neighbouring regions do not leak between sets). SFS or SBS (Tables 3-4) searches the 30 features
of Table 2 with the GRNN of eq. (4): trained on the training regions, judged by its balanced error
on the validation regions. Each subset along the path is then retrained on training + validation
and its error measured on the test regions: the error against the number of features (the paper's
Figure 6). :func:`run_selection` summarises the runs as in Figures 7-9 and Table 7: the mean and
spread of the error per subset size, how often each feature is among the first five selected, and
the five most frequent against the paper's (20, 17, 3, 6, 24).

Run ``r`` of a study seeded ``seed`` uses seed ``seed + r`` (situation ``n`` simulated with
``1000 * (seed + r) + n``), so runs are independent of where they run
(:class:`~.montecarlo.RunPool`). The regions are segmented with a seed threshold ``seed_db`` below
the node's default, so that enough clutter regions exist to learn the clutter class (at the
default almost none are found).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.fls import PAPER_FEATURES, FlsConfig
from sonar_tracking.core.fls.grnn import GRNN, balanced_error
from sonar_tracking.core.fls.selection import GrnnWrapper, sbs, sfs
from sonar_tracking.studies.fls_segmentation import RegionDataset, region_dataset, simulate_frames
from sonar_tracking.studies.montecarlo import Progress, RunPool

__all__ = ['SITUATIONS', 'SelectionStudy', 'run_selection', 'selection_run']

SITUATIONS = tuple(range(1, 15))
N_FEATURES = 30


@dataclass(frozen=True)
class SelectionStudy:
    """What every run of a selection study does (see module docstring)."""

    method: str = 'sfs'
    situations: tuple[int, ...] = SITUATIONS
    sweeps: int = 0
    preset: str = 'seaking675'
    sigma: float = 0.1
    seed_db: float = 4.0
    max_clutter_ratio: float = 2.0


def _dataset(seed: int, situations: tuple[int, ...], sweeps: int, preset: str, seed_db: float):
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
    cols = [f - 1 for f in subset]
    model = GRNN(sigma).fit(train.features[:, cols], train.labels)
    return balanced_error(test.labels, model.predict(test.features[:, cols]))


def _confusion(train, test, subset: tuple[int, ...], sigma: float, classes: list[str]) -> list[list[int]]:
    cols = [f - 1 for f in subset]
    pred = GRNN(sigma).fit(train.features[:, cols], train.labels).predict(test.features[:, cols])
    return [[int(np.sum((test.labels == a) & (pred == b))) for b in classes] for a in classes]


def selection_run(study: SelectionStudy, run_seed: int) -> dict:
    """One run: simulate, label, split, select, score (module docstring). Raises RuntimeError when
    the frames give too few labelled regions."""
    ds, n_frames = _dataset(run_seed, study.situations, study.sweeps, study.preset, study.seed_db)
    train, val, test, used = _split(ds, np.random.default_rng(run_seed), study.max_clutter_ratio)
    if min(len(train), len(val), len(test)) == 0 or len(np.unique(train.labels)) < 2:
        raise RuntimeError(f'seed {run_seed}: too few labelled regions ({ds.counts()}); simulate more sweeps')
    sigma = study.sigma
    wrapper = GrnnWrapper(train.features, train.labels, val.features, val.labels, sigma=sigma)
    search = sfs if study.method == 'sfs' else sbs
    path = search(wrapper, tuple(range(1, N_FEATURES + 1)))
    both = RegionDataset(np.concatenate([train.features, val.features]),
                         np.concatenate([train.labels, val.labels]), np.concatenate([train.frame, val.frame]))
    test_err = [_test_error(both, test, s, sigma) for s in path.subsets]
    best_k = int(np.argmin(path.errors)) + 1
    classes = sorted(used.counts())
    return {
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
    }


def run_selection(study: SelectionStudy, runs: int, seed: int = 0, pool: RunPool | None = None,
                  progress: Progress | None = None) -> dict:
    """Run the selection ``runs`` times (on ``pool``, else here); the JSON-ready result."""
    t0 = time.perf_counter()
    seeds = [seed + r for r in range(runs)]
    if pool is None:
        with RunPool(1) as here:
            per_run = here.map(selection_run, study, seeds, progress)
    else:
        per_run = pool.map(selection_run, study, seeds, progress)
    totals: dict[str, int] = {}
    for p in per_run:
        for k, v in p['class_counts'].items():
            totals[k] = totals.get(k, 0) + v
    all_features = tuple(range(1, N_FEATURES + 1))
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
    return {'method': study.method, 'runs': runs, 'seed': seed, 'situations': list(study.situations),
            'preset': study.preset, 'sigma': study.sigma, 'seed_db': study.seed_db, 'per_run': per_run,
            'summary': summary, 'wall_s': time.perf_counter() - t0}

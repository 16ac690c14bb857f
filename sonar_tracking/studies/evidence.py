"""The rules every comparative study follows, so that its tables survive a re-run on new seeds.

A study that compares methods on simulated Monte Carlo runs (``esc-table``, ``fls-table``,
``jipda``, and any later one such as an imaging-sonar study) goes through four steps, each a part
of this module:

1. **Seeds** (:class:`SeedSplit`). Calibration seeds, on which anything tuned is chosen, and at
   least two evaluation seeds, on which the methods are scored, each with the same number of
   runs. The sets must be disjoint, and the evaluation seeds must also avoid the seeds a study's
   defaults were tuned on (``tuned_on``). :func:`add_seed_arguments` and :func:`seed_split_from_args`
   give a command ``--calibration-seeds``, ``--seeds``, ``--runs`` and ``--calibration-runs``.
2. **Operating point** (:func:`choose_smallest_meeting`, :func:`choose_minimum`,
   :func:`paper_range`, :func:`grid_edge`). A setting such as the confirmation threshold T_c is
   swept over a grid on the calibration runs only and chosen per method by a stated rule; a chosen
   value outside the range the paper tries is marked as such, with the reason, and one at an end of
   its grid is flagged (the best value may lie beyond).
3. **Evaluation inside the run** (:func:`read_back`). Each method runs on the evaluation seeds
   with its chosen value set in its tracker, so track starts and anything that follows the
   confirmed tracks follow it too; the value each run's tracker actually holds is read back from
   its configuration and recorded.
4. **Comparison** (:class:`Correction`, :func:`paired_interval`, :func:`compare`,
   :func:`agreement`). Per comparison (method A minus method B on one metric, the methods sharing
   each run's random numbers) and per evaluation seed set: the mean paired difference with its
   Student-t interval at a Bonferroni-corrected level (the family of all intervals of a table at
   95 %) and, beside it, a rank interval (Hodges-Lehmann estimate, Wilcoxon signed-rank
   interval) that a few extreme runs cannot move, for heavy-tailed metrics; the same over the
   seed sets pooled; and the agreement check between the seed sets.

GOSPA is always given with its settings (:class:`GospaSpec`: cut-off ``c``, order ``p``,
``alpha``).

A new study, in short (``run_once(study, seed)`` one run of every method on the same data,
returning per method its per-run metrics and the setting its tracker holds)::

    split = seed_split_from_args(args, tuned_on=MY_TUNING_SEEDS)     # refuses overlapping sets
    costs = []
    for value in GRID:                                                # or a sweep after the runs
        runs = run_monte_carlo(run_once, replace(study, confirm=value), args.calibration_runs,
                               split.calibration[0], pool=pool)
        costs.append(np.mean([r['a']['gospa'] for r in runs]))
    choice = choose_minimum(GRID, costs)                              # or choose_smallest_meeting
    at_t_c = replace(study, confirm=choice['value'])                  # inside the run
    runs = {str(s): run_monte_carlo(run_once, at_t_c, args.runs, s, pool=pool) for s in split.evaluation}
    held = read_back(choice['value'], [r['a']['confirm'] for rs in runs.values() for r in rs])
    corr = Correction(intervals=n_comparisons * n_metrics)            # every interval of the table
    row = compare({s: {'a': [r['a']['gospa'] for r in rs], 'b': [r['b']['gospa'] for r in rs]}
                   for s, rs in runs.items()}, 'a', 'b', corr, heavy_tailed=True)

and :func:`format_comparisons` prints the comparison rows of the docs tables; the full run's JSON
goes to ``docs/results`` and a line in :data:`.results_docs.TABLES` keeps the page's table generated
from it.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np

from sonar_tracking.studies.metrics import GospaResult, gospa

__all__ = ['FAMILY_LEVEL', 'SeedError', 'SeedSplit', 'parse_seeds', 'add_seed_arguments', 'seed_split_from_args',
           'GospaSpec', 'choose_smallest_meeting', 'choose_minimum', 'choose_smallest_within_one_se',
           'grid_edge', 'paper_range', 'read_back',
           'Correction', 'paired_interval', 'rank_interval', 'agreement', 'compare', 'AGREEMENT_RULE',
           'format_interval', 'format_comparisons', 'split_line', 'per_run_values']

#: Family-wise confidence of all paired intervals of one table.
FAMILY_LEVEL = 0.95

#: How two evaluation seed sets are checked against each other (:func:`agreement`).
AGREEMENT_RULE = ('the two seed sets agree on a comparison when the difference of their mean paired differences '
                  'lies within its own t interval (the two sets independent, the table\'s corrected level)')


class SeedError(ValueError):
    """Seed sets that cannot give out-of-sample evidence; the message says why."""


def parse_seeds(text: str) -> tuple[int, ...]:
    """``'21,22'`` or ``'21-23'`` (or a mix) -> seeds in the order given; SeedError on anything else."""
    out: list[int] = []
    for item in (s.strip() for s in str(text).split(',')):
        if not item:
            continue
        lo, dash, hi = item.partition('-')
        try:
            if dash and lo:
                a, b = int(lo), int(hi)
                if b < a:
                    raise SeedError(f'seed range {item!r} runs backwards')
                out.extend(range(a, b + 1))
            else:
                out.append(int(item))
        except ValueError as exc:
            if isinstance(exc, SeedError):
                raise
            raise SeedError(f'seed {item!r} is not a whole number or a range A-B') from None
    if any(s < 0 for s in out):
        raise SeedError(f'seeds must be >= 0, got {text!r}')
    if not out:
        raise SeedError('no seeds given')
    if len(set(out)) != len(out):
        raise SeedError(f'seeds repeat in {text!r}')
    return tuple(out)


@dataclass(frozen=True)
class SeedSplit:
    """Calibration seeds (choose), evaluation seeds (score; at least ``min_evaluation``), and the seeds
    a study's defaults were tuned on (never scored). Construction refuses overlapping sets."""

    calibration: tuple[int, ...]
    evaluation: tuple[int, ...]
    tuned_on: tuple[int, ...] = ()
    min_evaluation: int = 2

    def __post_init__(self) -> None:
        if not self.calibration:
            raise SeedError('at least one calibration seed is needed')
        if len(self.evaluation) < self.min_evaluation:
            raise SeedError(f'at least {self.min_evaluation} evaluation seeds are needed (replication), '
                            f'got {list(self.evaluation)}')
        for name, seeds in (('calibration', self.calibration), ('evaluation', self.evaluation)):
            if len(set(seeds)) != len(seeds):
                raise SeedError(f'{name} seeds repeat: {list(seeds)}')
        both = sorted(set(self.calibration) & set(self.evaluation))
        if both:
            raise SeedError(f'calibration and evaluation seeds overlap: {both}')
        tuned = sorted(set(self.tuned_on) & set(self.evaluation))
        if tuned:
            raise SeedError(f'evaluation seeds {tuned} are among the seeds this study\'s defaults were tuned on '
                            f'({list(self.tuned_on)})')

    def describe(self) -> dict:
        """JSON-ready."""
        return {'calibration': list(self.calibration), 'evaluation': list(self.evaluation),
                'tuned_on': list(self.tuned_on)}


def add_seed_arguments(parser: Any, calibration: str, evaluation: str, runs: int, calibration_runs: int | None = None
                       ) -> None:
    """``--calibration-seeds``, ``--seeds``, ``--runs`` (per evaluation seed) and ``--calibration-runs``
    (per calibration seed; default ``--runs``) of a study command."""
    parser.add_argument('--calibration-seeds', default=calibration, metavar='S[,S|A-B]',
                        help=f'seeds of the calibration runs, where operating points are chosen '
                        f'(default {calibration})')
    parser.add_argument('--seeds', default=evaluation, metavar='S,S[,...]',
                        help=f'evaluation seeds, at least two, disjoint from the calibration seeds; each gets --runs '
                        f'runs and the table reports each and their agreement (default {evaluation})')
    parser.add_argument('--runs', type=int, default=runs, help=f'Monte Carlo runs per evaluation seed (default {runs})')
    parser.add_argument('--calibration-runs', type=int, default=calibration_runs,
                        help='Monte Carlo runs per calibration seed (default: --runs)')


def seed_split_from_args(args: Any, tuned_on: Iterable[int] = ()) -> SeedSplit:
    """The :class:`SeedSplit` of parsed :func:`add_seed_arguments` (SeedError says what is wrong);
    fills ``args.calibration_runs`` from ``args.runs`` when not given."""
    if getattr(args, 'calibration_runs', None) is None:
        args.calibration_runs = args.runs
    if args.runs < 2 or args.calibration_runs < 2:
        raise SeedError('--runs and --calibration-runs must be >= 2')
    return SeedSplit(parse_seeds(args.calibration_seeds), parse_seeds(args.seeds), tuple(tuned_on))


@dataclass(frozen=True)
class GospaSpec:
    """GOSPA settings (Rahmathullah, Garcia-Fernandez & Svensson 2017): cut-off ``c`` [m], order
    ``p``, ``alpha`` (2: the missed / false / localisation split)."""

    c: float
    p: float = 2.0
    alpha: float = 2.0

    def __call__(self, truth_xy, estimate_xy) -> GospaResult:
        """GOSPA between true positions ``(m, 2)`` and estimated ones ``(n, 2)``."""
        return gospa(truth_xy, estimate_xy, self.c, self.p, self.alpha)

    def describe(self) -> dict:
        """JSON-ready."""
        return {'c': self.c, 'p': self.p, 'alpha': self.alpha}

    def text(self) -> str:
        """``GOSPA (c = 20 m, p = 2, alpha = 2)``."""
        return f'GOSPA (c = {self.c:g} m, p = {self.p:g}, alpha = {self.alpha:g})'


def choose_smallest_meeting(grid: Sequence[float], rates: Sequence[float], target: float) -> dict:
    """The smallest grid value whose ``rates`` entry is at most ``target`` (``grid`` ascending; rates
    need not be monotone: the first that meets counts); the largest value, flagged, when none
    does. JSON-ready: ``index``, ``value``, ``rate``, ``meets_target``."""
    g, r = np.asarray(grid, dtype=float), np.asarray(rates, dtype=float)
    if g.shape != r.shape or g.ndim != 1 or not len(g):
        raise ValueError(f'grid and rates must be equal 1-d, got {g.shape} and {r.shape}')
    ok = np.flatnonzero(r <= target)
    j = int(ok[0]) if len(ok) else len(g) - 1
    return {'index': j, 'value': float(g[j]), 'rate': float(r[j]), 'meets_target': bool(len(ok))}


def choose_minimum(grid: Sequence[float], costs: Sequence[float]) -> dict:
    """The grid value of least ``costs`` (the smallest such value on a tie; NaN costs never win).
    JSON-ready: ``index``, ``value``, ``cost``."""
    g, c = np.asarray(grid, dtype=float), np.asarray(costs, dtype=float)
    if g.shape != c.shape or g.ndim != 1 or not len(g):
        raise ValueError(f'grid and costs must be equal 1-d, got {g.shape} and {c.shape}')
    if not np.isfinite(c).any():
        raise ValueError('no finite cost to choose from')
    j = int(np.nanargmin(np.where(np.isfinite(c), c, np.nan)))
    return {'index': j, 'value': float(g[j]), 'cost': float(c[j])}


def choose_smallest_within_one_se(grid: Sequence[float], samples: Sequence[Sequence[float]],
                                  allowed: Sequence[bool] | None = None) -> dict:
    """The one-standard-error rule (Breiman et al., *Classification and Regression Trees*, 1984, §3.4.3)
    for a score to maximise: of the ``allowed`` grid values (``grid`` ascending; all when None), the
    one of largest mean ``samples`` sets a bar, its mean less its standard error; the smallest allowed
    value whose mean reaches the bar wins. Differences within the best value's noise then go to the
    smallest value instead of to chance. No value allowed: the smallest grid value, flagged.
    JSON-ready: ``index``, ``value``, ``means``, ``ses``, ``bar`` and ``allowed_any``."""
    g = np.asarray(grid, dtype=float)
    if g.ndim != 1 or not len(g) or len(samples) != len(g):
        raise ValueError(f'grid and samples must be of equal length, got {len(g)} and {len(samples)}')
    ok = np.ones(len(g), bool) if allowed is None else np.asarray(allowed, dtype=bool)
    arrays = [np.asarray(s, dtype=float) for s in samples]
    means = np.array([a.mean() if len(a) else math.nan for a in arrays])
    ses = np.array([a.std(ddof=1) / math.sqrt(len(a)) if len(a) > 1 else math.nan for a in arrays])
    out = {'means': [float(m) for m in means], 'ses': [float(s) for s in ses]}
    ok &= np.isfinite(means)
    if not ok.any():
        return {'index': 0, 'value': float(g[0]), 'bar': math.nan, 'allowed_any': False, **out}
    best = int(np.flatnonzero(ok)[np.argmax(means[ok])])
    bar = float(means[best] - (ses[best] if math.isfinite(ses[best]) else 0.0))
    j = int(np.flatnonzero(ok & (means >= bar))[0])
    return {'index': j, 'value': float(g[j]), 'bar': bar, 'allowed_any': True, **out}


def grid_edge(index: int, grid: Sequence[float]) -> str | None:
    """``'lowest'`` or ``'highest'`` when a choice lies at that end of its grid (the best value may lie
    beyond it: extend the grid, or say so), else None."""
    if index == len(grid) - 1:
        return 'highest'
    return 'lowest' if index == 0 else None


def paper_range(value: float, low: float | None, high: float | None, reason: str = '') -> dict:
    """Whether a chosen ``value`` lies in the range the paper tries (``None`` bounds: open; both
    None: the paper gives none), and when it does not, ``reason`` (why the rule went there)."""
    if low is None and high is None:
        return {'paper_range': None, 'in_paper_range': None, 'reason': None}
    inside = (low is None or value >= low - 1e-12) and (high is None or value <= high + 1e-12)
    return {'paper_range': [low, high], 'in_paper_range': bool(inside), 'reason': None if inside else reason}


def read_back(chosen: float, values: Iterable[float]) -> dict:
    """The values evaluation runs' trackers held (each read from its configuration) against the
    chosen one: ``read_back`` the distinct values, ``runs``, ``equal`` when every run held ``chosen``."""
    v = [float(x) for x in values]
    return {'chosen': float(chosen), 'read_back': sorted(set(v)), 'runs': len(v),
            'equal': bool(v) and all(x == float(chosen) for x in v)}


@dataclass(frozen=True)
class Correction:
    """Bonferroni correction for the ``intervals`` paired intervals of one table: each at level
    ``1 - (1 - family_level) / intervals``, so that all hold together with ``family_level``."""

    intervals: int
    family_level: float = FAMILY_LEVEL

    def __post_init__(self) -> None:
        if self.intervals < 1 or not 0 < self.family_level < 1:
            raise ValueError(f'need intervals >= 1 and 0 < family_level < 1, got {self.intervals}, '
                             f'{self.family_level}')

    @property
    def level(self) -> float:
        """Confidence level of each interval."""
        return 1.0 - (1.0 - self.family_level) / self.intervals

    def describe(self) -> dict:
        """JSON-ready."""
        return {'method': 'bonferroni', 'intervals': self.intervals, 'family_level': self.family_level,
                'level': self.level}

    def text(self) -> str:
        """One sentence for a table's caption."""
        return (f'Bonferroni over the table\'s {self.intervals} paired intervals: each at '
                f'{100 * self.level:.4g} %, all together at {100 * self.family_level:g} %')


def _signed_rank_cdf(n: int) -> np.ndarray:
    """P(T+ <= k), k = 0 .. n(n+1)/2, of the Wilcoxon signed-rank statistic without ties (exact)."""
    top = n * (n + 1) // 2
    counts = np.zeros(top + 1)
    counts[0] = 1.0
    for r in range(1, n + 1):
        counts[r:] = counts[r:] + counts[:-r].copy()
    return np.cumsum(counts) / 2.0 ** n


def rank_interval(d, level: float) -> dict:
    """Hodges-Lehmann estimate (median of the Walsh averages ``(d_i + d_j) / 2, i <= j``) of the
    paired differences ``d`` and its Wilcoxon signed-rank interval at ``level``: the order statistics
    ``k`` and ``M + 1 - k`` of the ``M`` Walsh averages, ``k`` from the exact null distribution up to
    60 runs and its normal approximation above. Zeros and ties are kept (the interval is then
    approximate). ``low``/``high`` are None when the runs are too few for the level."""
    from scipy.stats import norm
    d = np.sort(np.asarray(d, dtype=np.float64))
    n = d.size
    if n == 0:
        return {'estimate': None, 'low': None, 'high': None}
    i, j = np.triu_indices(n)
    walsh = np.sort(0.5 * (d[i] + d[j]))
    m = walsh.size
    est = float(np.median(walsh))
    a = 1.0 - level
    if n <= 60:
        cdf = _signed_rank_cdf(n)
        k = int(np.searchsorted(cdf, a / 2.0, side='right'))     # P(T+ <= k - 1) <= a / 2
    else:
        z = float(norm.ppf(1.0 - a / 2.0))
        k = int(math.floor(m / 2.0 - z * math.sqrt(n * (n + 1) * (2 * n + 1) / 24.0)))
    if k < 1:
        return {'estimate': est, 'low': None, 'high': None}
    return {'estimate': est, 'low': float(walsh[k - 1]), 'high': float(walsh[m - k])}


def paired_interval(a, b, level: float = 0.95) -> dict:
    """Mean of ``a - b`` over the runs where both are finite, its Student-t interval at ``level``
    (``half``, ``low``, ``high``, standard error ``se``) and the rank interval of the same differences
    (:func:`rank_interval`: ``rank_estimate``, ``rank_low``, ``rank_high``). With common random
    numbers (the methods share each run) the run-to-run noise cancels in the difference. Interval
    entries are None below two runs."""
    from scipy.stats import t as student_t
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    d = d[np.isfinite(d)]
    out: dict[str, Any] = {'difference': None, 'half': None, 'low': None, 'high': None, 'se': None,
                           'runs': int(d.size), 'level': level}
    if d.size == 0:
        out.update(rank_estimate=None, rank_low=None, rank_high=None)
        return out
    mean = float(d.mean())
    out['difference'] = mean
    if d.size >= 2:
        se = float(d.std(ddof=1) / math.sqrt(d.size))
        half = float(student_t.ppf(0.5 + level / 2.0, d.size - 1) * se)
        out.update(se=se, half=half, low=mean - half, high=mean + half)
    r = rank_interval(d, level)
    out.update(rank_estimate=r['estimate'], rank_low=r['low'], rank_high=r['high'])
    return out


def agreement(first: dict, second: dict, level: float) -> dict:
    """Check two independent seed sets' paired differences (:func:`paired_interval`) against each
    other (:data:`AGREEMENT_RULE`): ``delta`` the difference of their means, ``half`` its t interval
    (Welch degrees of freedom), ``agree`` when ``|delta| <= half``; ``overlap`` whether the two t
    intervals overlap. ``agree`` is None when either lacks an interval."""
    from scipy.stats import t as student_t
    if first.get('se') is None or second.get('se') is None:
        return {'delta': None, 'half': None, 'agree': None, 'overlap': None}
    delta = first['difference'] - second['difference']
    v1, v2 = first['se'] ** 2, second['se'] ** 2
    n1, n2 = first['runs'], second['runs']
    if v1 + v2 == 0.0:
        return {'delta': delta, 'half': 0.0, 'agree': delta == 0.0, 'overlap': delta == 0.0}
    df = (v1 + v2) ** 2 / ((v1 ** 2 / (n1 - 1) if v1 else 0.0) + (v2 ** 2 / (n2 - 1) if v2 else 0.0))
    half = float(student_t.ppf(0.5 + level / 2.0, df) * math.sqrt(v1 + v2))
    overlap = first['low'] <= second['high'] and second['low'] <= first['high']
    return {'delta': float(delta), 'half': half, 'agree': bool(abs(delta) <= half), 'overlap': bool(overlap)}


def compare(samples: Mapping[str, Mapping[str, Sequence[float]]], first: str, second: str, correction: Correction,
            heavy_tailed: bool = False) -> dict:
    """One comparison ``first - second`` of per-run values ``samples[seed][method]`` (runs in the same
    order for both methods of a seed): per seed set and pooled over them, :func:`paired_interval` at
    the corrected level, and :func:`agreement` for every two seed sets (``agree`` when all agree).
    ``heavy_tailed`` marks the rank interval as one a table must show."""
    level = correction.level
    per_seed = {s: paired_interval(v[first], v[second], level) for s, v in samples.items()}
    pooled = paired_interval(np.concatenate([np.asarray(v[first], float) for v in samples.values()]),
                             np.concatenate([np.asarray(v[second], float) for v in samples.values()]), level)
    checks = {f'{a}|{b}': agreement(per_seed[a], per_seed[b], level) for a, b in combinations(per_seed, 2)}
    flags = [c['agree'] for c in checks.values()]
    return {'first': first, 'second': second, 'heavy_tailed': heavy_tailed, 'seeds': per_seed, 'pooled': pooled,
            'agreement': checks, 'agree': None if any(f is None for f in flags) else all(flags)}


def per_run_values(values, digits: int = 6) -> list[float | None]:
    """Per-run figures for a JSON file: rounded to ``digits`` significant digits, None where not
    finite (the intervals are computed from the unrounded values)."""
    return [float(f'{v:.{digits}g}') if math.isfinite(v) else None for v in np.asarray(values, dtype=float).tolist()]


def format_interval(iv: dict, digits: int = 3, rank: bool = False) -> str:
    """``+0.123 ± 0.045`` (t), with ``rank`` also `` [HL +0.100: +0.020, +0.190]``; ``n/a`` without data."""
    if iv.get('difference') is None:
        return 'n/a'
    text = f'{iv["difference"]:+.{digits}f}' + ('' if iv.get('half') is None else f' ± {iv["half"]:.{digits}f}')
    if rank and iv.get('rank_estimate') is not None:
        lo, hi = iv.get('rank_low'), iv.get('rank_high')
        span = '' if lo is None else f': {lo:+.{digits}f}, {hi:+.{digits}f}'
        text += f' [HL {iv["rank_estimate"]:+.{digits}f}{span}]'
    return text


def split_line(iv: dict) -> str:
    """Where a t interval lies: ``> 0``, ``< 0`` or ``~0`` (contains zero); ``n/a`` without one."""
    if iv.get('low') is None:
        return 'n/a'
    return '> 0' if iv['low'] > 0 else '< 0' if iv['high'] < 0 else '~0'


def format_comparisons(rows: Sequence[tuple[str, str, dict]], seeds: Sequence[str], digits: int = 3) -> list[str]:
    """Markdown rows ``| group | comparison | pooled | seed A | seed B | ... | agree |`` for
    ``rows = [(group, label, compare(...)), ...]``; heavy-tailed comparisons show the rank interval
    beside the t interval (pooled column)."""
    head = ['group', 'comparison', 'pooled: mean ± t [HL: rank interval]'] + [f'seed {s}' for s in seeds] + ['agree']
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for group, label, c in rows:
        cells = [group, label, format_interval(c['pooled'], digits, rank=c['heavy_tailed'])]
        cells += [format_interval(c['seeds'][s], digits) for s in seeds]
        cells.append('n/a' if c['agree'] is None else ('yes' if c['agree'] else '**no**'))
        lines.append('| ' + ' | '.join(cells) + ' |')
    return lines

"""The JIPDA table, out of sample: IMM-JIPDA against IMM-IPDA in every cell (geometry x condition) of
:mod:`.jipda_study`, each tracker at its own T_c chosen on calibration seeds.

The rules are those of :mod:`.evidence`:

1. **Calibration** (calibration seeds only), per cell and method. *Screen*: the trackers confirm at
   the lowest T_c of :data:`T_GRID` and T_c is swept after the runs; the T_c of least mean GOSPA
   (:data:`~.jipda_study.GOSPA`). *Inside the run*: the screened T_c and its two neighbours on the
   grid are each run inside the run on the same calibration runs (confirmation decides which
   duplicate tracks are removed, so the sweep is only a screen), and the one of least mean GOSPA
   is chosen. A T_c above 0.99, the largest the ESC paper's Algorithm 1 tries for this tracker, is
   marked with the reason (its calibration GOSPA against the best at or below 0.99).
2. **Evaluation** on each evaluation seed (the same runs each), every tracker built with its T_c,
   read back from its configuration in each run.
3. **Comparison**: JIPDA minus IPDA on every metric of :data:`~.jipda_study.METRICS`, per seed set and
   pooled, t intervals Bonferroni-corrected over the table, the rank interval beside GOSPA and
   swaps (heavy-tailed), and the agreement of the seed sets. The table says per cell whether
   JIPDA's lead on GOSPA holds (pooled interval below zero and the seed sets agree).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from sonar_tracking.studies.evidence import (
    AGREEMENT_RULE,
    Correction,
    SeedSplit,
    choose_minimum,
    compare,
    format_comparisons,
    format_interval,
    grid_edge,
    paper_range,
    per_run_values,
    read_back,
    split_line,
)
from sonar_tracking.studies.jipda_study import CELLS, GOSPA, METHODS, METRICS, for_condition, run_once
from sonar_tracking.studies.montecarlo import Progress, RunPool, run_monte_carlo

__all__ = ['T_GRID', 'TUNED_ON', 'PAPER_T_C_MAX', 'HEAVY', 'calibrate', 'run_table', 'format_table']

#: T_c values the calibration sweeps (a track's existence stays below about 0.9998 here, so a higher
#: T_c would confirm nothing).
T_GRID = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.98, 0.99, 0.995, 0.998, 0.999, 0.9993, 0.9995, 0.9997)
#: Seeds of the in-model JIPDA figures of docs/experiments/2026-11-25-jipda.md: never evaluation seeds.
TUNED_ON = (1,)
#: The largest T_c the ESC paper's Algorithm 1 tries.
PAPER_T_C_MAX = 0.99
#: Metrics whose rank interval the table shows.
HEAVY = ('gospa', 'swaps')
LABELS = {'gospa': 'GOSPA [m]', 'missed': 'missed targets / scan', 'false': 'false tracks / scan',
          'swaps': 'swaps / run', 'coalescence': 'coalescence', 'cttr': 'CTTR'}


def _runs(study, seeds, runs: int, pool: RunPool | None, label: str, progress: bool | None) -> list[dict]:
    out: list[dict] = []
    for s in seeds:
        out += run_monte_carlo(run_once, study, runs, s, pool=pool,
                               progress=Progress(f'{label}, seed {s}', runs, enabled=progress))
    return out


def calibrate(study, seeds, runs: int, pool: RunPool | None = None, grid=T_GRID, progress: bool | None = None
              ) -> dict:
    """Per method: the T_c of least mean GOSPA, screened by the sweep and chosen inside the run among
    the screened value and its neighbours (module docstring)."""
    sweep = _runs(replace(study, sweep_grid=tuple(grid)), seeds, runs, pool, 'calibration, sweep', progress)
    swept = {m: np.mean([r[m]['swept_gospa'] for r in sweep], axis=0) for m in METHODS}
    screened = {m: choose_minimum(grid, swept[m]) for m in METHODS}
    tried: dict[str, dict[int, float]] = {m: {} for m in METHODS}
    for offset in (0, -1, 1):
        idx = {m: screened[m]['index'] + offset for m in METHODS if 0 <= screened[m]['index'] + offset < len(grid)}
        if not idx:
            continue
        st = replace(study, confirm_by_method=tuple((m, float(grid[j])) for m, j in idx.items()))
        res = _runs(st, seeds, runs, pool, 'calibration, in the run', progress)
        for m, j in idx.items():
            tried[m][j] = float(np.mean([r[m]['gospa'] for r in res]))
    out = {}
    at_paper = [j for j, t in enumerate(grid) if t <= PAPER_T_C_MAX]
    for m in METHODS:
        js = sorted(tried[m])
        c = choose_minimum([grid[j] for j in js], [tried[m][j] for j in js])
        inside = [j for j in js if grid[j] <= PAPER_T_C_MAX]
        if inside:
            k = min(inside, key=lambda j: tried[m][j])
            reason = (f'least calibration GOSPA inside the run: {c["cost"]:.3f} m at T_c {c["value"]:g} against '
                      f'{tried[m][k]:.3f} m at {grid[k]:g}')
        else:
            k = min(at_paper, key=lambda j: swept[m][j]) if at_paper else 0
            reason = (f'least calibration GOSPA: {c["cost"]:.3f} m at T_c {c["value"]:g} inside the run; the sweep\'s '
                      f'best at or below {PAPER_T_C_MAX} was {swept[m][k]:.3f} m at {grid[k]:g}')
        out[m] = {'t_c': c['value'], 'gospa': c['cost'], 'screened': {**screened[m], 'swept_gospa': swept[m].tolist()},
                  'in_run': {str(grid[j]): tried[m][j] for j in js},
                  'grid_edge': grid_edge(js[c['index']], grid),
                  **paper_range(c['value'], None, PAPER_T_C_MAX, reason)}
    return out


def run_table(split: SeedSplit, runs: int, calibration_runs: int | None = None, pool: RunPool | None = None,
              scans: int | None = None, cells=CELLS, grid=T_GRID, progress: bool | None = None) -> dict:
    """Every cell: calibration on ``split.calibration`` (``calibration_runs`` runs each, default
    ``runs``), evaluation on each seed of ``split.evaluation`` (``runs`` each); ``scans`` overrides
    the study length (reduced runs). JSON-ready, every run's figures included."""
    calibration_runs = calibration_runs or runs
    seeds = [str(s) for s in split.evaluation]
    corr = Correction(max(1, len(cells) * len(METRICS)))
    out = {'seeds': split.describe(), 'runs': runs, 'calibration_runs': calibration_runs, 't_grid': list(grid),
           'gospa': GOSPA.describe(), 'correction': corr.describe(), 'agreement_rule': AGREEMENT_RULE, 'cells': []}
    for geometry, condition in cells:
        study = for_condition(condition, geometry, **({'scans': scans} if scans else {}))
        label = f'{geometry}, {condition}'
        cal = calibrate(study, split.calibration, calibration_runs, pool, grid, progress)
        ev = replace(study, confirm_by_method=tuple((m, cal[m]['t_c']) for m in METHODS))
        per_seed = {}
        for s in split.evaluation:
            per_seed[str(s)] = run_monte_carlo(run_once, ev, runs, s, pool=pool,
                                               progress=Progress(f'{label}, evaluation seed {s}', runs,
                                                                 enabled=progress))
        values = {s: {m: {k: np.array([r[m][k] for r in per_seed[s]], dtype=float) for k in METRICS}
                      for m in METHODS} for s in seeds}
        methods = {}
        for m in METHODS:
            methods[m] = {'calibration': cal[m],
                          't_c_read_back': read_back(cal[m]['t_c'], [r[m]['confirm'] for s in seeds
                                                                     for r in per_seed[s]]),
                          'means': {s: {k: _nanmean(values[s][m][k]) for k in METRICS} for s in seeds},
                          'pooled': {k: _nanmean(np.concatenate([values[s][m][k] for s in seeds])) for k in METRICS},
                          'runs_with_swaps': float(np.mean(np.concatenate([values[s][m]['swaps'] for s in seeds]) > 0))}
        comparisons = [{'metric': k, **compare({s: {'jipda': values[s]['jipda'][k], 'ipda': values[s]['ipda'][k]}
                                                for s in seeds}, 'jipda', 'ipda', corr, heavy_tailed=k in HEAVY)}
                       for k in METRICS]
        g = comparisons[0]
        holds = g['pooled']['high'] is not None and g['pooled']['high'] < 0 and bool(g['agree'])
        out['cells'].append({'geometry': geometry, 'condition': condition, 'study': _describe(ev), 'methods': methods,
                             'comparisons': comparisons, 'gospa_lead_holds': holds,
                             'per_run': {s: {'parameter': per_run_values([r['parameter'] for r in per_seed[s]]),
                                             **{m: {k: per_run_values(values[s][m][k]) for k in METRICS}
                                                for m in METHODS}} for s in seeds}})
    return out


def _describe(study) -> dict:
    d = {k: getattr(study, k) for k in study.__dataclass_fields__}
    d['cell_m'] = study.cell
    return {k: [list(x) if isinstance(x, tuple) else x for x in v] if isinstance(v, tuple) else v
            for k, v in d.items()}


def _nanmean(v: np.ndarray) -> float | None:
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else None


def _fmt(v: float | None, digits: int) -> str:
    return 'n/a' if v is None else f'{v:.{digits}f}'


def _t_c(cal: dict) -> str:
    """T_c with ``*`` above the paper's range and ``†`` at an end of the grid."""
    return f'{cal["t_c"]:g}' + ('*' if cal['in_paper_range'] is False else '') + ('†' if cal.get('grid_edge') else '')


def _both(methods: dict, metric: str, digits: int) -> str:
    return ' / '.join(_fmt(methods[m]['pooled'][metric], digits) for m in METHODS)


def format_table(result: dict) -> str:
    """The docs/results tables (markdown) of :func:`run_table`'s result: per cell the operating
    points and pooled means, then every paired comparison."""
    seeds = [str(s) for s in result['seeds']['evaluation']]
    g = result['gospa']
    corr = Correction(result['correction']['intervals'], result['correction']['family_level'])
    lines = [f'Calibration seeds {", ".join(map(str, result["seeds"]["calibration"]))} ({result["calibration_runs"]} '
             f'runs each): T_c per cell and tracker of least mean GOSPA, screened by the sweep over '
             f'{", ".join(f"{t:g}" for t in result["t_grid"])}, chosen inside the run. Evaluation seeds '
             f'{" / ".join(seeds)} ({result["runs"]} runs each, pooled here); GOSPA c = {g["c"]:g} m, p = {g["p"]:g}, '
             f'alpha = {g["alpha"]:g}, of the confirmed tracks.', '',
             '| geometry | condition | T_c IPDA / JIPDA (read back) | GOSPA [m] IPDA / JIPDA | JIPDA − IPDA, GOSPA '
             '(pooled) | lead on GOSPA | swaps / run | CTTR | false tracks / scan | missed / scan |',
             '|---|---|---|---|---|---|---|---|---|---|']
    for c in result['cells']:
        ms = c['methods']
        tc = ' / '.join(_t_c(ms[m]['calibration']) for m in METHODS)
        back = 'same' if all(ms[m]['t_c_read_back']['equal'] for m in METHODS) else 'DIFFERS'
        gos = c['comparisons'][0]
        lead = ('holds' if c['gospa_lead_holds'] else
                f'does not hold ({split_line(gos["pooled"])}' + ('' if gos['agree'] else ', seed sets disagree') + ')')

        lines.append(f'| {c["geometry"]} | {c["condition"]} | {tc} ({back}) | {_both(ms, "gospa", 2)} | '
                     f'{format_interval(gos["pooled"], 2)} | {lead} | {_both(ms, "swaps", 2)} | '
                     f'{_both(ms, "cttr", 3)} | {_both(ms, "false", 3)} | {_both(ms, "missed", 3)} |')
    lines += ['', '* T_c above 0.99, the largest the ESC paper\'s Algorithm 1 tries (reasons in the JSON, '
              '`calibration.reason`); † at an end of the grid.', '',
              f'Paired per-run differences JIPDA − IPDA (CTTR: higher is better; the others: lower); {corr.text()}; '
              f'{AGREEMENT_RULE}.', '']
    rows = [(f'{c["geometry"]}, {c["condition"]}', LABELS[k['metric']], k) for c in result['cells']
            for k in c['comparisons']]
    lines += format_comparisons(rows, seeds, digits=3)
    return '\n'.join(lines)

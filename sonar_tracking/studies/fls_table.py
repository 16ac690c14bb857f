"""The FLS paper's comparison as one table, out of sample: methods on the same frames, ranked on the
capped CLE, paired, on two evaluation seed sets.

Runs Table 5 situations (by default the crossings 8-11) with every method on the same frames and
random stream (:func:`~.fls_study.run_once`), scoring the confirmed tracks (what the tracker
reports). The rules are those of :mod:`.evidence`:

1. **Calibration** (calibration seeds only). The GPF's confirmation setting ``birth.confirm_hits``
   is the operating point: every value of :data:`HITS_GRID` is run inside the run, and per method
   and situation the value of least mean GOSPA (:data:`GOSPA`) over the calibration runs is
   chosen. The FLS paper gives no confirmation rule, so no paper range applies. The GPF's other
   defaults were tuned on the seeds in :data:`TUNED_ON`, which are never evaluation seeds.
2. **Evaluation** (each evaluation seed, the same runs each), every method's tracker built with its
   chosen value, read back from the tracker's configuration in each run. Per run and method:

   * ``cle_capped``: the capped CLE (eq. 19), mean over the moving targets and frames, a frame in
     which the target has no owner or its owner is farther than the gate counting as the gate
     (1.5 m): losing the target costs here, so the table ranks on it;
   * ``lost``: lost frames per target; ``breaks``: track breaks per target (times a target took a
     new owner after its owner ended);
   * ``gospa``: mean GOSPA per frame (c = the gate, p = 2, alpha = 2) of the targets against the
     confirmed tracks;
   * ``cle``: the uncapped CLE of the tracked frames only (the paper's figure; kept as a column,
     not ranked on: a method that drops its track there loses nothing);
   * ``identity``: the run kept identity through the crossing (1 / 0; none when no target had an
     owner before it).
3. **Comparison**: the first method minus each other on capped CLE, lost frames, track breaks and
   GOSPA, per evaluation seed and pooled, t intervals Bonferroni-corrected over the table, the rank
   interval beside each (all four are heavy-tailed: a few runs in which a track is carried off set
   the mean), and the agreement of the seed sets (:func:`~.evidence.compare`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from sonar_tracking.studies.evidence import (
    AGREEMENT_RULE,
    Correction,
    GospaSpec,
    SeedSplit,
    choose_minimum,
    compare,
    format_comparisons,
    paper_range,
    per_run_values,
    read_back,
)
from sonar_tracking.studies.fls_study import FlsStudy, parse_methods, run_cle, run_once, situation_scenario
from sonar_tracking.studies.montecarlo import Progress, RunPool, run_monte_carlo

__all__ = ['TABLE_SITUATIONS', 'TABLE_METHODS', 'TUNED_ON', 'HITS_GRID', 'GOSPA', 'METRICS', 'COMPARED',
           'per_run_metrics', 'calibrate', 'run_table', 'format_table']

TABLE_SITUATIONS = (8, 9, 10, 11)
TABLE_METHODS = ('af', 'af18', 'mf', 'wf')

#: Seeds the GPF's defaults were tuned or checked on (docs/experiments/2026-11-21-fls-gpf-study.md):
#: never evaluation seeds.
TUNED_ON = (7, 11, 2026, *range(3000, 3010), 4000, 4001)

#: ``birth.confirm_hits`` values tried on the calibration runs.
HITS_GRID = (1, 2, 3, 4)

#: GOSPA of the FLS tables: cut-off at the scoring gate.
GOSPA = GospaSpec(c=1.5, p=2.0, alpha=2.0)

#: Per-run metrics in table order; the compared ones (all heavy-tailed).
METRICS = ('cle_capped', 'lost', 'breaks', 'gospa', 'cle', 'identity')
COMPARED = ('cle_capped', 'lost', 'breaks', 'gospa')
LABELS = {'cle_capped': 'capped CLE [m]', 'lost': 'lost frames / target', 'breaks': 'track breaks / target',
          'gospa': 'GOSPA [m]', 'cle': 'CLE of tracked frames [m]', 'identity': 'identity kept'}


def per_run_metrics(study: FlsStudy, runs: list[dict]) -> dict[str, dict[str, np.ndarray]]:
    """Per method, per run, the metrics of the module docstring and ``confirm`` (the value read back)."""
    out = {}
    for m in study.methods:
        sc = [r['scores'][m] for r in runs]
        ident = []
        for s in sc:
            k = s['identity']
            ident.append(np.nan if k is None or np.isnan(k).all() else float(np.nan_to_num(k, nan=1.0).all()))
        out[m] = {'cle_capped': np.array([s['capped'].mean() for s in sc]),
                  'lost': np.array([s['lost'].sum(axis=1).mean() for s in sc]),
                  'breaks': np.array([(s['acquisitions'] - 1).clip(0).mean() for s in sc], dtype=float),
                  'gospa': np.array([r['gospa'][m].mean() for r in runs]),
                  'cle': np.array([run_cle(s['cle']) for s in sc]),
                  'identity': np.array(ident),
                  'confirm': np.array([r['confirm'][m] for r in runs])}
    return out


def _runs(study: FlsStudy, seeds, runs: int, pool: RunPool | None, label: str, progress: bool | None) -> list:
    out: list = []
    for s in seeds:
        out += run_monte_carlo(run_once, study, runs, s, pool=pool,
                               progress=Progress(f'{label}, seed {s}', runs, enabled=progress))
    return out


def calibrate(study: FlsStudy, seeds, runs: int, pool: RunPool | None = None, grid=HITS_GRID,
              progress: bool | None = None) -> dict:
    """Per method: the ``birth.confirm_hits`` of ``grid`` with the least mean GOSPA over the
    calibration runs, each value run inside the run; the mean GOSPA of every value too."""
    costs: dict[str, list[float]] = {m: [] for m in study.methods}
    for h in grid:
        st = replace(study, confirm_by_method=tuple((m, h) for m in study.methods))
        res = _runs(st, seeds, runs, pool, f'calibration, confirm_hits {h}', progress)
        for m in study.methods:
            costs[m].append(float(np.mean([r['gospa'][m].mean() for r in res])))
    out = {}
    for m in study.methods:
        c = choose_minimum(grid, costs[m])
        out[m] = {'confirm_hits': int(c['value']), 'gospa': c['cost'], 'grid': list(grid), 'gospa_by_value': costs[m],
                  **paper_range(c['value'], None, None)}
    return out


def run_table(split: SeedSplit, runs: int, calibration_runs: int | None = None, pool: RunPool | None = None,
              situations=TABLE_SITUATIONS, methods=TABLE_METHODS, grid=HITS_GRID, progress: bool | None = None
              ) -> dict:
    """Every situation: calibration on ``split.calibration`` (``calibration_runs`` runs each, default
    ``runs``), evaluation on each seed of ``split.evaluation`` (``runs`` each); JSON-ready."""
    methods = parse_methods(','.join(methods))
    calibration_runs = calibration_runs or runs
    seeds = [str(s) for s in split.evaluation]
    corr = Correction(max(1, len(situations) * (len(methods) - 1) * len(COMPARED)))
    out = {'seeds': split.describe(), 'runs': runs, 'calibration_runs': calibration_runs, 'methods': list(methods),
           'hits_grid': list(grid), 'gospa': GOSPA.describe(), 'correction': corr.describe(),
           'agreement_rule': AGREEMENT_RULE, 'situations': []}
    for n in situations:
        study = FlsStudy(situation_scenario(n), methods=methods, score_confirmed=True, gospa=GOSPA)
        gate = study.gate
        cal = calibrate(study, split.calibration, calibration_runs, pool, grid, progress)
        ev = replace(study, confirm_by_method=tuple((m, cal[m]['confirm_hits']) for m in methods))
        metrics, corrections = {}, {m: np.zeros(3, np.int64) for m in methods}
        for s in split.evaluation:
            res = run_monte_carlo(run_once, ev, runs, s, pool=pool,
                                  progress=Progress(f'situation {n}, evaluation seed {s}', runs, enabled=progress))
            metrics[str(s)] = per_run_metrics(ev, res)
            for m in methods:
                corrections[m] += np.sum([r['corrections'][m] for r in res], axis=0)
        rows = {}
        for m in methods:
            image, region, coast = corrections[m].tolist()
            pooled = {k: np.concatenate([metrics[s][m][k] for s in seeds]) for k in METRICS}
            rows[m] = {'calibration': cal[m],
                       'confirm_hits_read_back': read_back(cal[m]['confirm_hits'],
                                                           [v for s in seeds for v in metrics[s][m]['confirm']]),
                       'pooled': {k: _nanmean(pooled[k]) for k in METRICS},
                       'identity_runs': int(np.isfinite(pooled['identity']).sum()),
                       'evaluation': {s: {k: _nanmean(metrics[s][m][k]) for k in METRICS} for s in seeds},
                       'per_run': {s: {k: per_run_values(metrics[s][m][k]) for k in METRICS} for s in seeds},
                       'corrections': {'image': image, 'region': region, 'coasting': coast,
                                       'image_share': image / (image + region) if image + region else None}}
        ranking = sorted(methods, key=lambda m: rows[m]['pooled']['cle_capped'])
        first = methods[0]
        comparisons = []
        for m in methods[1:]:
            for k in COMPARED:
                c = compare({s: {first: metrics[s][first][k], m: metrics[s][m][k]} for s in seeds}, first, m, corr,
                            heavy_tailed=True)
                comparisons.append({'metric': k, **c})
        out['situations'].append({'situation': n, 'scenario': study.scenario, 'gate': gate, 'methods': rows,
                                  'ranking': ranking, 'comparisons': comparisons})
    return out


def _nanmean(v: np.ndarray) -> float | None:
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else None


def _num(v, digits: int) -> str:
    return 'n/a' if v is None else f'{v:.{digits}f}'


def _pct(v) -> str:
    return 'n/a' if v is None else f'{100 * v:.1f} %'


def format_table(result: dict) -> str:
    """The docs/results tables (markdown) of :func:`run_table`'s result: per situation the methods
    ranked on capped CLE with the other metrics, then the paired comparisons."""
    seeds = [str(s) for s in result['seeds']['evaluation']]
    g = result['gospa']
    corr = Correction(result['correction']['intervals'], result['correction']['family_level'])
    first = result['methods'][0]
    lines = [f'Calibration seeds {", ".join(map(str, result["seeds"]["calibration"]))} ({result["calibration_runs"]} '
             f'runs each): birth.confirm_hits per method and situation of least mean GOSPA among '
             f'{", ".join(map(str, result["hits_grid"]))}, each run inside the run. Evaluation seeds '
             f'{" / ".join(seeds)} ({result["runs"]} runs each, pooled below), confirmed tracks scored; capped CLE: a '
             f'frame without the target within the gate counts as the gate; GOSPA c = {g["c"]:g} m, p = {g["p"]:g}, '
             f'alpha = {g["alpha"]:g}.', '',
             '| situation | rank | method | confirm_hits (read back) | capped CLE [m] | lost frames / target | '
             'track breaks / target | GOSPA [m] | CLE of tracked frames [m] | identity kept | image share |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    for s in result['situations']:
        for rank, m in enumerate(s['ranking'], 1):
            row = s['methods'][m]
            p = row['pooled']
            rb = row['confirm_hits_read_back']
            back = 'same' if rb['equal'] else 'differs: ' + ', '.join(f'{v:g}' for v in rb['read_back'])
            lines.append(f'| {s["situation"]} | {rank} | {m} | {row["calibration"]["confirm_hits"]} ({back}) | '
                         f'{_num(p["cle_capped"], 3)} | {_num(p["lost"], 2)} | {_num(p["breaks"], 3)} | '
                         f'{_num(p["gospa"], 3)} | {_num(p["cle"], 3)} | {_pct(p["identity"])} | '
                         f'{_pct(row["corrections"]["image_share"])} |')
    lines += ['', f'Paired per-run differences {first} − method (lower is better on all four); {corr.text()}; '
              f'{AGREEMENT_RULE}.', '']
    rows = [(str(s['situation']), f'{c["first"]} − {c["second"]}, {LABELS[c["metric"]]}', c)
            for s in result['situations'] for c in s['comparisons']]
    lines += format_comparisons(rows, seeds, digits=3)
    return '\n'.join(lines)

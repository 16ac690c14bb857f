"""The ESC paper's comparison at its operating point, out of sample: T_c per method for a CFT rate
of 0.005 chosen on calibration seeds, then every method run at its T_c on evaluation seeds.

The paper compares ESC with fixed thresholds after Algorithm 1 has set the confirmation threshold
T_c for a rate of confirmed false tracks (CFT) of about 0.005, the rate counted as Table 1 defines
it: scans with a confirmed false track / (scans x runs) (:func:`~.metrics.cft_scan_rate`). The
studies are Scenario 1 (lambda 1.2 and 0.8, IPDA) and Scenario 2 (IMM-IPDA), every method on the
same sectors in each run (:func:`~.esc_study.run_once`). The rules are those of :mod:`.evidence`:

1. **Calibration** (calibration seeds only). *Screen*: the trackers confirm at the grid's lowest
   T_c and T_c is swept after the runs (:class:`~.confirmation.ConfirmationSweep`); per method the
   smallest T_c of :data:`~.confirmation.T_GRID` whose swept CFT-scan rate is at most ``cft_target``.
   *Check inside the run*: a tracker that confirms at T_c during the run is a different system
   (only detections no confirmed track validated start tracks, and Scenario 2's ESC measures the
   density at the confirmed track of highest existence), so the screened T_c is run inside the
   run on the same calibration runs; while its CFT-scan rate there is above the target, T_c moves
   one grid step up, and while the next step down still meets it, one step down (at most
   ``max_steps`` moves). The chosen T_c is the last one that met the target inside the run. A
   value above 0.99, the largest the paper's Algorithm 1 tries (``T_c = 0.99 : -0.01 : T_c,Min``),
   is marked with the reason (no T_c up to 0.99 meets the target, with the swept rate at 0.99).
2. **Evaluation** (each evaluation seed, the same runs each). Every method's tracker is built
   with its chosen T_c; each run reads it back from the tracker's configuration
   (:func:`~.evidence.read_back`). Per run and method: the CTTR over the second half of the scans
   (the share of those scans with a confirmed true track), the mean GOSPA over the second half
   (:data:`GOSPA`: c = 20 m, p = 2, alpha = 2, the target against the confirmed tracks) and the
   share of all scans with a confirmed false track (its mean over runs is the Table 1 rate).
3. **Comparison**: ESC minus each fixed threshold on CTTR and GOSPA, paired per run, per evaluation
   seed and pooled, t intervals Bonferroni-corrected over the table's intervals, the rank interval
   beside GOSPA (heavy-tailed), and the agreement of the seed sets (:func:`~.evidence.compare`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sonar_tracking.studies.confirmation import T_GRID
from sonar_tracking.studies.esc_study import PAPER_DESIRED_DENSITY, StudyConfig, parse_methods, run_once
from sonar_tracking.studies.evidence import (
    AGREEMENT_RULE,
    Correction,
    GospaSpec,
    SeedSplit,
    choose_smallest_meeting,
    compare,
    format_comparisons,
    paper_range,
    per_run_values,
    read_back,
)
from sonar_tracking.studies.metrics import cft_scan_rate
from sonar_tracking.studies.montecarlo import Progress, RunPool, run_monte_carlo

__all__ = ['TableStudy', 'TABLE_STUDIES', 'TUNED_ON', 'PAPER_T_C_MAX', 'GOSPA', 'screen', 'calibrate',
           'per_run_metrics', 'run_table', 'format_table']

#: Seeds the ESC defaults were measured or tuned on (the reproduction: 1; the integrator gain: 7 and 77;
#: docs/experiments/2026-11-21-esc-paper-reproduction.md): never evaluation seeds.
TUNED_ON = (1, 7, 77)

#: The largest T_c the paper's Algorithm 1 tries (line 7: ``T_c = 0.99 : -0.01 : T_c,Min``).
PAPER_T_C_MAX = 0.99

#: GOSPA of the ESC table: the one target against the confirmed tracks.
GOSPA = GospaSpec(c=20.0, p=2.0, alpha=2.0)

#: Per-run metrics of the evaluation, and which are compared (with the better direction).
METRICS = ('cttr', 'gospa', 'cft_scans')
COMPARED = (('cttr', False), ('gospa', True))      # (metric, heavy-tailed)


@dataclass(frozen=True)
class TableStudy:
    """One row group of the table: a name and the study it runs."""

    name: str
    study: StudyConfig


TABLE_STUDIES = (
    TableStudy('Scenario 1, lambda 1.2', StudyConfig('scenario1', 50, 1.2, methods=parse_methods(
        'esc,fixed:2,fixed:4,fixed:6'), desired_density=PAPER_DESIRED_DENSITY['scenario1'])),
    TableStudy('Scenario 1, lambda 0.8', StudyConfig('scenario1', 50, 0.8, methods=parse_methods(
        'esc,fixed:2,fixed:4,fixed:6'), desired_density=PAPER_DESIRED_DENSITY['scenario1'])),
    TableStudy('Scenario 2', StudyConfig('scenario2', 100, methods=parse_methods('esc,fixed:3,fixed:4'),
                                         desired_density=PAPER_DESIRED_DENSITY['scenario2'])),
)


def _runs(study: StudyConfig, seeds: tuple[int, ...], runs: int, pool: RunPool | None, label: str,
          progress: bool | None) -> list[dict]:
    """``runs`` runs of ``study`` for each of ``seeds``, concatenated in seed order."""
    out: list[dict] = []
    for s in seeds:
        out += run_monte_carlo(run_once, study, runs, s, pool=pool,
                               progress=Progress(f'{label}, seed {s}', runs, enabled=progress))
    return out


def screen(study: StudyConfig, runs: list[dict], cft_target: float) -> dict:
    """Per method, from sweep runs (``sweep_tc``): the smallest T_c of the grid whose swept CFT-scan
    rate meets ``cft_target`` (:func:`~.evidence.choose_smallest_meeting`) and the swept rate at the
    paper's largest T_c."""
    out = {}
    at_paper = int(np.argmin(np.abs(T_GRID - PAPER_T_C_MAX)))
    for m in study.methods:
        nf = np.array([r[m.name]['n_false_t'] for r in runs])              # (runs, scans, T)
        rate = (nf > 0).mean(axis=(0, 1))
        out[m.name] = {**choose_smallest_meeting(T_GRID, rate, cft_target),
                       'rate_at_paper_max': float(rate[at_paper])}
    return out


def _in_run_rates(study: StudyConfig, index: dict[str, int], seeds: tuple[int, ...], runs: int,
                  pool: RunPool | None, progress: bool | None) -> dict[str, dict]:
    """CFT-scan rate and runs with a CFT of each method of ``index`` run inside the run at
    ``T_GRID[index[method]]`` on the calibration runs."""
    methods = tuple(m for m in study.methods if m.name in index)
    st = replace(study, methods=methods, sweep_tc=False,
                 confirm_by_method=tuple((n, float(T_GRID[j])) for n, j in index.items()))
    results = _runs(st, seeds, runs, pool, 'calibration, in the run', progress)
    out = {}
    for n in index:
        nf = np.array([r[n]['n_false'] for r in results])
        out[n] = {'t_c': float(T_GRID[index[n]]), 'cft_scan_rate': cft_scan_rate(nf),
                  'runs_with_cft': int((nf > 0).any(axis=1).sum())}
    return out


def calibrate(study: StudyConfig, seeds: tuple[int, ...], runs: int, pool: RunPool | None = None,
              cft_target: float = 0.005, max_steps: int = 3, progress: bool | None = None) -> dict:
    """T_c per method on the calibration runs: screened by the sweep, then checked and moved inside
    the run (module docstring). Per method: ``t_c``, ``meets_target`` (inside the run), the
    screen, every T_c tried inside the run (``path``) and the paper-range record."""
    sweep_runs = _runs(replace(study, sweep_tc=True), seeds, runs, pool, 'calibration, sweep', progress)
    screened = screen(study, sweep_runs, cft_target)
    state = {n: {'index': s['index'], 'path': [], 'best': None, 'direction': 0, 'done': False}
             for n, s in screened.items()}
    top = len(T_GRID) - 1
    for step in range(max_steps + 1):
        todo = {n: st['index'] for n, st in state.items() if not st['done']}
        if not todo:
            break
        rates = _in_run_rates(study, todo, seeds, runs, pool, progress)
        for n, r in rates.items():
            st = state[n]
            st['path'].append({**r, 'index': st['index']})
            ok = r['cft_scan_rate'] <= cft_target
            if ok:
                st['best'] = st['index']
            if st['direction'] == 0:
                st['direction'] = -1 if ok else 1
            nxt = st['index'] + st['direction']
            # Going up, the first T_c that meets ends the search; going down, the first that fails.
            st['done'] = (ok if st['direction'] > 0 else not ok) or not 0 <= nxt <= top or step == max_steps
            if not st['done']:
                st['index'] = nxt
    out = {}
    for n, st in state.items():
        met = st['best'] is not None
        j = st['best'] if met else st['path'][-1]['index']
        r = next(p for p in st['path'] if p['index'] == j)
        sc = screened[n]
        failed = [p for p in st['path'] if p['t_c'] <= PAPER_T_C_MAX and p['cft_scan_rate'] > cft_target]
        if failed:
            p = max(failed, key=lambda q: q['t_c'])
            reason = (f'inside the run on the calibration runs, T_c {p["t_c"]:.5g} gave a CFT-scan rate of '
                      f'{p["cft_scan_rate"]:.4f} > {cft_target:g}')
        else:
            reason = (f'the sweep on the calibration runs: no T_c <= {PAPER_T_C_MAX} meets the CFT-scan rate '
                      f'{cft_target:g} (swept rate at {PAPER_T_C_MAX}: {sc["rate_at_paper_max"]:.4f})')
        out[n] = {'t_c': float(T_GRID[j]), 'meets_target': met, 'cft_scan_rate': r['cft_scan_rate'],
                  'runs_with_cft': r['runs_with_cft'], 'screened': sc, 'path': st['path'],
                  **paper_range(float(T_GRID[j]), None, PAPER_T_C_MAX, reason)}
    return out


def per_run_metrics(study: StudyConfig, runs: list[dict]) -> dict[str, dict[str, np.ndarray]]:
    """Per method, per run: ``cttr`` and ``gospa`` over the second half of the scans, ``cft_scans`` the
    share of all scans with a confirmed false track, and ``confirm`` the T_c read back."""
    half = study.scans // 2
    out = {}
    for m in study.methods:
        rec = [r[m.name] for r in runs]
        out[m.name] = {'cttr': np.array([r['has_ctt'][half:].mean() for r in rec]),
                       'gospa': np.array([r['gospa'][half:].mean() for r in rec]),
                       'cft_scans': np.array([(r['n_false'] > 0).mean() for r in rec]),
                       'confirm': np.array([r['confirm'] for r in rec])}
    return out


def run_table(split: SeedSplit, runs: int, calibration_runs: int | None = None, pool: RunPool | None = None,
              scans: int | None = None, cft_target: float = 0.005, studies=TABLE_STUDIES, max_steps: int = 3,
              progress: bool | None = None) -> dict:
    """Every study of the table: calibration on ``split.calibration`` (``calibration_runs`` runs each,
    default ``runs``), evaluation on every seed of ``split.evaluation`` (``runs`` each); ``scans``
    overrides the studies' lengths (reduced runs). The JSON-ready result."""
    calibration_runs = calibration_runs or runs
    seeds = [str(s) for s in split.evaluation]
    n_intervals = sum((len(t.study.methods) - 1) * len(COMPARED) for t in studies)
    corr = Correction(n_intervals)
    out = {'seeds': split.describe(), 'runs': runs, 'calibration_runs': calibration_runs, 'cft_target': cft_target,
           'max_steps': max_steps, 'gospa': GOSPA.describe(), 'correction': corr.describe(),
           'agreement_rule': AGREEMENT_RULE, 'studies': []}
    for t in studies:
        study = replace(t.study, scans=scans) if scans else t.study
        study = replace(study, gospa=GOSPA)
        label = t.name
        cal = calibrate(study, split.calibration, calibration_runs, pool, cft_target, max_steps,
                        progress=progress)
        ev_study = replace(study, confirm_by_method=tuple((n, c['t_c']) for n, c in cal.items()))
        metrics = {}
        for s in split.evaluation:
            res = run_monte_carlo(run_once, ev_study, runs, s, pool=pool,
                                  progress=Progress(f'{label}, evaluation seed {s}', runs, enabled=progress))
            metrics[str(s)] = per_run_metrics(ev_study, res)
        methods = {}
        for m in study.methods:
            n = m.name
            methods[n] = {'calibration': cal[n],
                          't_c_read_back': read_back(cal[n]['t_c'],
                                                     [v for s in seeds for v in metrics[s][n]['confirm']]),
                          'evaluation': {s: {'cft_scan_rate': float(metrics[s][n]['cft_scans'].mean()),
                                             'meets_target': bool(metrics[s][n]['cft_scans'].mean() <= cft_target),
                                             'cttr': float(metrics[s][n]['cttr'].mean()),
                                             'gospa': float(metrics[s][n]['gospa'].mean()),
                                             'per_run': {k: per_run_values(metrics[s][n][k]) for k in METRICS}}
                                         for s in seeds}}
        first = study.methods[0].name
        comparisons = []
        for m in study.methods[1:]:
            for k, heavy in COMPARED:
                c = compare({s: {first: metrics[s][first][k], m.name: metrics[s][m.name][k]} for s in seeds},
                            first, m.name, corr, heavy_tailed=heavy)
                comparisons.append({'metric': k, **c})
        out['studies'].append({'name': t.name, 'scenario': study.scenario, 'scans': study.scans,
                               'lam': study.lam if study.scenario == 'scenario1' else None,
                               'methods': methods, 'comparisons': comparisons})
    return out


def _pair(values: list[float], digits: int) -> str:
    return ' / '.join(f'{v:.{digits}f}' for v in values)


def format_table(result: dict) -> str:
    """The docs/results tables (markdown) of :func:`run_table`'s result: operating points and
    means per evaluation seed, then the paired comparisons."""
    seeds = [str(s) for s in result['seeds']['evaluation']]
    g = result['gospa']
    corr = Correction(result['correction']['intervals'], result['correction']['family_level'])
    lines = [f'Calibration seeds {", ".join(map(str, result["seeds"]["calibration"]))} '
             f'({result["calibration_runs"]} runs each): T_c per method for a CFT-scan rate <= '
             f'{result["cft_target"]:g} (Table 1), screened by the sweep, checked inside the run. Evaluation seeds '
             f'{" / ".join(seeds)} ({result["runs"]} runs each), every tracker at its T_c; CTTR and GOSPA '
             f'(c = {g["c"]:g} m, p = {g["p"]:g}, alpha = {g["alpha"]:g}) over the second half of the scans.', '',
             '| study | method | T_c | T_c read back | calibration CFT scans / scan (runs with one) '
             f'| CFT scans / scan, seed {" / ".join(seeds)} | CTTR | GOSPA [m] |', '|---|---|---|---|---|---|---|---|']
    for s in result['studies']:
        for name, m in s['methods'].items():
            cal = m['calibration']
            tc = f'{cal["t_c"]:.5g}' + ('' if cal['meets_target'] else ' (target not met)')
            if cal['in_paper_range'] is False:
                tc += ' (above the paper\'s 0.99)'
            rb = m['t_c_read_back']
            back = ('= T_c' if rb['equal'] else 'differs: ' + ', '.join(f'{v:.5g}' for v in rb['read_back']))
            ev = m['evaluation']
            lines.append(f'| {s["name"]} | {name} | {tc} | {back} ({rb["runs"]} runs) | {cal["cft_scan_rate"]:.4f} '
                         f'({cal["runs_with_cft"]}) | {_pair([ev[k]["cft_scan_rate"] for k in seeds], 4)} | '
                         f'{_pair([ev[k]["cttr"] for k in seeds], 3)} | {_pair([ev[k]["gospa"] for k in seeds], 2)} |')
    lines += ['', f'Paired per-run differences ESC − method (CTTR: higher is better; GOSPA: lower is better); '
              f'{corr.text()}; {AGREEMENT_RULE}.', '']
    rows = []
    for s in result['studies']:
        for c in s['comparisons']:
            label = {'cttr': 'CTTR', 'gospa': 'GOSPA [m]'}[c['metric']]
            rows.append((s['name'], f'{c["first"]} − {c["second"]}, {label}', c))
    lines += format_comparisons(rows, seeds, digits=3)
    outside = [(s['name'], n, m['calibration']) for s in result['studies'] for n, m in s['methods'].items()
               if m['calibration']['in_paper_range'] is False]
    if outside:
        lines += ['', 'T_c outside the paper\'s range (Algorithm 1 tries 0.99 and below):']
        lines += [f'- {st}, {n}: {cal["t_c"]:.5g}: {cal["reason"]}' for st, n, cal in outside]
    return '\n'.join(lines)

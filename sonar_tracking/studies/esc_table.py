"""The ESC paper's comparison at its operating point: T_c per method for a CFT rate of 0.005.

The paper compares ESC with fixed thresholds after Algorithm 1 has set the confirmation threshold
T_c for a rate of confirmed false tracks (CFT) of about 0.005, the rate counted as Table 1 defines
it: scans with a confirmed false track / (scans x runs) (:func:`~.metrics.cft_scan_rate`). This
study runs Scenario 1 (lambda 1.2 and 0.8, IPDA) and Scenario 2 (IMM-IPDA) with every method on
the same sectors (:func:`~.esc_study.run_once` with ``sweep_tc``), then per method takes the
smallest T_c of :data:`~.confirmation.T_GRID` whose CFT-scan rate is at most ``cft_target`` (the
largest of the grid when none is) and reports at that T_c:

* both CFT counts: the Table 1 rate (scans with one or more) and false tracks per scan;
* the CTTR over the second half of the scans (mean over runs), and per run its mean;
* the paired per-run difference ESC minus each fixed threshold of that CTTR, with its 95 %
  Student-t interval (:func:`~.metrics.paired_difference`): the methods share each run's sectors.

Each method's T_c is chosen on the same runs it is scored on (as Algorithm 1 does), which favours
no method over another.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sonar_tracking.studies.confirmation import T_GRID
from sonar_tracking.studies.esc_study import PAPER_DESIRED_DENSITY, StudyConfig, parse_methods, run_once
from sonar_tracking.studies.metrics import cft_scan_rate, confirmed_false_track_rate, paired_difference
from sonar_tracking.studies.montecarlo import Progress, RunPool, run_monte_carlo

__all__ = ['TableStudy', 'TABLE_STUDIES', 'operating_point', 'run_table', 'format_table']


@dataclass(frozen=True)
class TableStudy:
    """One row group of the table: a name and the study it runs."""

    name: str
    study: StudyConfig


TABLE_STUDIES = (
    TableStudy('Scenario 1, lambda 1.2', StudyConfig('scenario1', 50, 1.2, methods=parse_methods(
        'esc,fixed:2,fixed:4,fixed:6'), desired_density=PAPER_DESIRED_DENSITY['scenario1'], sweep_tc=True)),
    TableStudy('Scenario 1, lambda 0.8', StudyConfig('scenario1', 50, 0.8, methods=parse_methods(
        'esc,fixed:2,fixed:4,fixed:6'), desired_density=PAPER_DESIRED_DENSITY['scenario1'], sweep_tc=True)),
    TableStudy('Scenario 2', StudyConfig('scenario2', 100, methods=parse_methods('esc,fixed:3,fixed:4'),
                                         desired_density=PAPER_DESIRED_DENSITY['scenario2'], sweep_tc=True)),
)


def operating_point(study: StudyConfig, runs: list[dict], cft_target: float = 0.005) -> dict:
    """Per method: the chosen T_c, both CFT counts there, CTTR (second half) and its per-run
    means, and for every other method the paired difference of the first method minus it."""
    half = study.scans // 2
    out = {}
    for m in study.methods:
        nf = np.array([r[m.name]['n_false_t'] for r in runs])          # (runs, scans, T)
        has = np.array([r[m.name]['has_ctt_t'] for r in runs])
        scan_rate = (nf > 0).mean(axis=(0, 1))
        ok = np.flatnonzero(scan_rate <= cft_target)
        j = int(ok[0]) if len(ok) else len(T_GRID) - 1
        per_run = has[:, half:, j].mean(axis=1)
        out[m.name] = {'t_c': float(T_GRID[j]), 'meets_target': bool(len(ok)),
                       'cft_scan_rate': cft_scan_rate(nf[:, :, j]),
                       'cft_per_scan': confirmed_false_track_rate(nf[:, :, j]),
                       'cttr_second_half': float(per_run.mean()), 'cttr_run': per_run.tolist()}
    first = study.methods[0].name
    for name, row in out.items():
        if name != first:
            row['paired_first_minus'] = paired_difference(np.array(out[first]['cttr_run']),
                                                          np.array(row['cttr_run']))
    return out


def run_table(runs: int, seed: int, pool: RunPool | None = None, scans: int | None = None,
              cft_target: float = 0.005, studies=TABLE_STUDIES, progress: bool | None = None) -> dict:
    """Every study of the table, ``runs`` runs each seeded ``seed`` (``scans`` overrides the
    studies' lengths, for reduced runs); the JSON-ready result."""
    out = {'runs': runs, 'seed': seed, 'cft_target': cft_target, 'studies': []}
    for t in studies:
        study = replace(t.study, scans=scans) if scans else t.study
        results = run_monte_carlo(run_once, study, runs, seed, pool=pool,
                                  progress=Progress(t.name, runs, enabled=progress))
        out['studies'].append({'name': t.name, 'scenario': study.scenario, 'scans': study.scans,
                               'lam': study.lam if study.scenario == 'scenario1' else None,
                               'methods': operating_point(study, results, cft_target)})
    return out


def format_table(result: dict) -> str:
    """The docs/results table (markdown) of :func:`run_table`'s result."""
    lines = [f'{result["runs"]} runs, seed {result["seed"]}; T_c per method for a CFT-scan rate <= '
             f'{result["cft_target"]:g} (Table 1); CTTR over the second half of the scans; ESC - method: paired '
             f'per-run difference, 95 % interval', '',
             '| study | method | T_c | CFT scans / scan | CFT tracks / scan | CTTR | ESC − method |',
             '|---|---|---|---|---|---|---|']
    for s in result['studies']:
        for name, m in s['methods'].items():
            p = m.get('paired_first_minus')
            diff = '' if p is None else ('n/a' if p['difference'] is None else
                                         f'{p["difference"]:+.3f}' + ('' if p['ci95'] is None else
                                                                     f' ± {p["ci95"]:.3f}'))
            tc = f'{m["t_c"]:.4g}' + ('' if m['meets_target'] else ' (target not met)')
            lines.append(f'| {s["name"]} | {name} | {tc} | {m["cft_scan_rate"]:.4f} | {m["cft_per_scan"]:.4f} | '
                         f'{m["cttr_second_half"]:.3f} | {diff} |')
    return '\n'.join(lines)

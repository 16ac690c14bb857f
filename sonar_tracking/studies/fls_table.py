"""The FLS paper's crossing comparison (situations 8-11) as one table: fusions side by side, paired.

Runs the crossing situations of Table 5 with every method on the same frames and random stream
(:func:`~.fls_study.run_once`) and reports per situation and method:

* the mean CLE over the moving targets (eq. 19; mean over runs of each run's mean, :func:`~.fls_study.run_cle`);
* the paired per-run difference of the first method (``af``) minus each other method, with its
  95 % Student-t interval (:func:`~.metrics.paired_difference`);
* the share of runs that kept identity through the crossing;
* where the corrections come from: the share of corrected track-frames corrected by the image
  (the window features) rather than by re-finding a segmented region.

The default methods set the project's adaptive fusion (``af``: eq. 18 with the crossing switch)
beside eq. 18 alone (``af18``), MF and WF.
"""
from __future__ import annotations

from sonar_tracking.studies.fls_study import FlsStudy, parse_methods, run_once, situation_scenario, summarise
from sonar_tracking.studies.montecarlo import Progress, RunPool, run_monte_carlo

__all__ = ['TABLE_SITUATIONS', 'TABLE_METHODS', 'run_table', 'format_table']

TABLE_SITUATIONS = (8, 9, 10, 11)
TABLE_METHODS = ('af', 'af18', 'mf', 'wf')


def run_table(runs: int, seed: int, pool: RunPool | None = None, situations=TABLE_SITUATIONS,
              methods=TABLE_METHODS, progress: bool | None = None) -> dict:
    """Every situation, ``runs`` runs each seeded ``seed``, every method on the same frames; JSON-ready."""
    methods = parse_methods(','.join(methods))
    out = {'runs': runs, 'seed': seed, 'methods': list(methods), 'situations': []}
    for n in situations:
        study = FlsStudy(situation_scenario(n), methods=methods)
        results = run_monte_carlo(run_once, study, runs, seed, pool=pool,
                                  progress=Progress(f'situation {n}', runs, enabled=progress))
        summary = summarise(study, results)
        rows = {}
        for m, res in summary.items():
            finite = [v for v in res['cle_run'] if v is not None]
            rows[m] = {'cle': sum(finite) / len(finite) if finite else None,
                       'paired_first_minus': res.get('paired_with_first'),
                       'identity_kept_rate': res.get('identity_kept_rate'),
                       'identity_runs': res.get('identity_runs'),
                       'corrections': res['corrections']}
        out['situations'].append({'situation': n, 'scenario': study.scenario, 'methods': rows})
    return out


def format_table(result: dict) -> str:
    """The docs/results table (markdown) of :func:`run_table`'s result."""
    methods = result['methods']
    first = methods[0]
    head = (['situation'] + [f'{m} CLE' for m in methods] + [f'{first} − {m}' for m in methods[1:]]
            + [f'identity kept {" / ".join(methods)}', f'image share {" / ".join(methods)}'])
    lines = [f'{result["runs"]} runs, seed {result["seed"]}; mean CLE over the moving targets [m]; {first} − method: '
             'paired per-run difference of the mean CLE, 95 % interval; image share: corrected track-frames '
             'corrected by the window features rather than by a re-found region', '',
             '| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for s in result['situations']:
        rows = s['methods']
        cle = [_num(rows[m]['cle'], 3) for m in methods]
        diffs = []
        for m in methods[1:]:
            p = rows[m]['paired_first_minus'] or {}
            diffs.append('n/a' if p.get('difference') is None else f'{p["difference"]:+.3f}'
                         + ('' if p.get('ci95') is None else f' ± {p["ci95"]:.3f}'))
        ident = ' / '.join(_pct(rows[m]['identity_kept_rate']) for m in methods)
        share = ' / '.join(_pct(rows[m]['corrections']['image_share']) for m in methods)
        lines.append('| ' + ' | '.join([str(s['situation'])] + cle + diffs + [ident, share]) + ' |')
    return '\n'.join(lines)


def _num(v, digits: int) -> str:
    return 'n/a' if v is None else f'{v:.{digits}f}'


def _pct(v) -> str:
    return 'n/a' if v is None else f'{100 * v:.1f} %'

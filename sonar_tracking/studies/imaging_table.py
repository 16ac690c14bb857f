"""The imaging-sonar study (``sonar_eval imaging``) under the evidence rules (:mod:`.evidence`): the
Oculus M750d-class preset's CFAR front end and point trackers on the simulated head
(:mod:`.imaging_study`), operating points chosen on calibration seeds and scored on two disjoint
evaluation seed sets.

Parts (``--parts``):

* ``roc``: detection probability of the diver against false detections per frame for each CFAR
  variant (CA, GO, OS) at the design false-alarm probabilities of :data:`PFA_GRID`, and for the FLS
  region path (the preset's ``fls_features`` section, its regions as the detections) at the seed
  levels of :data:`SEED_DB_GRID`; ESC and structure rejection off (the fixed operating points
  themselves; nothing is chosen). Runs of
  :data:`ROC_FRAMES` frames each, starting at a time drawn per run over the scenario.
* ``esc``: ESC holding the false-detection density when the clutter changes shape: Rayleigh speckle,
  then K (shape 0.5) from frame :data:`ESC_SWITCH`, on a moving platform (fresh speckle each frame),
  structure rejection off, on a window of the head (:data:`ESC_WINDOW`: its beams and bins at the
  Oculus's spacing). ESC's input is the preset's: with no track, the count of the frame's
  detections over the window's area. The operating point, the desired density rho_D, is chosen on the calibration
  runs: the density ESC measures at the design scale on Rayleigh frames. Scored: the mean density of
  frames :data:`ESC_SCORED` over rho_D, with ESC on (the criterion: within 20 %) and off (by how much
  CA-CFAR exceeds its design rate under K), the two sharing each run's frames.
* ``static``: the empty scene with frozen speckle (``imaging_empty``), full-size frames, for
  :data:`STATIC_FRAMES` frames: confirmed tracks (all false).
* ``diver``: ``imaging_diver`` (120 s), reduced frames (:data:`REDUCED`): CTTR, false confirmed
  tracks per hour with its Poisson 95 % upper bound, track breaks, duplicates, GOSPA, P_D. The
  operating point, rho_D, is chosen on the calibration runs from :func:`rho_grid` (:data:`RHO_FACTORS`
  times the head's preset value) by :data:`DIVER_RULE` (the smallest rho_D if none is free of false
  tracks).
* ``school``: ``imaging_school``, reduced frames, IMM-JIPDA against IMM-IPDA on the same detections,
  each tracker at its T_c of least mean GOSPA on the calibration runs (:data:`T_GRID`), the paired
  GOSPA difference with Bonferroni-corrected intervals per evaluation seed set and pooled. The
  detector is set for fish (:data:`FISH`), as a user watching fish sets it over the diver preset.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from sonar_tracking.studies.evidence import (
    AGREEMENT_RULE,
    Correction,
    SeedSplit,
    choose_minimum,
    choose_smallest_within_one_se,
    compare,
    format_comparisons,
    per_run_values,
    read_back,
)
from sonar_tracking.studies.imaging_study import (
    CLEARANCE,
    GATE,
    GOSPA,
    ImagingRun,
    front_end,
    poisson_upper,
    run_once,
)
from sonar_tracking.studies.montecarlo import RunPool, run_seeds

__all__ = ['PARTS', 'PFA_GRID', 'CFAR_METHODS', 'RHO_FACTORS', 'DIVER_RULE', 'rho_grid', 'T_GRID', 'REDUCED',
           'TUNED_ON', 'run_table', 'format_table', 'Sizes', 'with_comparisons']

PARTS = ('roc', 'esc', 'static', 'diver', 'school')
SENSOR = 'oculus_m750d'
#: Reduced frames of the long parts: every second beam and bin (256 x 500).
REDUCED = 2
PFA_GRID = (1e-3, 1e-4, 1e-5, 1e-6)
CFAR_METHODS = ('ca', 'go', 'os')
#: The FLS region path's operating points: its seed level above the background [dB] (the preset: 6).
SEED_DB_GRID = (2.0, 3.0, 4.0, 6.0)
REGION_GROW_DB = 3.0   # the region path's default growth level, lowered with a seed below it
ROC_FRAMES = 5
ESC_WINDOW = (('imaging.n_beams', 128), ('imaging.fov_deg', 32.5), ('imaging.n_bins', 256),
              ('imaging.range_max', 7.78))
ESC_SWITCH = 200
ESC_SCORED = (400, 500)
ESC_SPEED = 1.0
STATIC_FRAMES = 12_000
#: The diver's desired densities as factors of the head's preset value (the Oculus's 5e-4 /m^2 gives 2e-4,
#: 5e-4 and 2e-3): a narrow head's fan is smaller, so its preset asks for more false detections per m^2.
RHO_FACTORS = (0.4, 1.0, 4.0)
T_GRID = (0.95, 0.99, 0.995)
#: What a user watching fish sets over the diver preset: the fish's size, and blobs merged over one beam
#: width and 12 cm of range (4 beams and 4 bins of the full frame), not over a diver's 3 beam widths
#: and 30 cm, which join fish 1 m apart.
FISH = (('cells.target_size', 0.3), ('cells.merge_beams', 4), ('cells.merge_bins', 4))
#: The seeds the preset values were tried on while they were built (docs/experiments): never evaluation seeds.
TUNED_ON = (1, 3, 5, 501, 701, 801)   # 501 (calibration), 701, 801: the diver's confirmation rules
_OFF = (('esc.enabled', False), ('structure.enabled', False), ('threshold.minimum', 1.0))


class Sizes:
    """The simulated head, and the runs and frames of each part (the defaults: the committed full run;
    the suite passes smaller)."""

    def __init__(self, runs: int, calibration_runs: int, roc_runs: int | None = None, esc_runs: int | None = None,
                 static_frames: int = STATIC_FRAMES, diver_frames: int = 0, school_frames: int = 0,
                 scale: int = REDUCED, static_scale: int = 1, esc_frames: int = ESC_SCORED[1],
                 sensor: str = SENSOR) -> None:
        self.sensor = sensor
        self.runs, self.calibration_runs = runs, calibration_runs
        self.roc_runs = roc_runs or runs
        self.esc_runs = esc_runs or runs
        self.static_frames, self.diver_frames, self.school_frames = static_frames, diver_frames, school_frames
        self.scale, self.static_scale, self.esc_frames = scale, static_scale, esc_frames

    def describe(self) -> dict:
        return dict(vars(self))


def _runs(run: ImagingRun, seeds, n: int, pool: RunPool | None, progress=None) -> dict[str, list]:
    """``n`` runs per seed set, all sets in one batch (the runs of both sets share the processes)."""
    seqs = [q for s in seeds for q in run_seeds(s, n)]
    out = pool.map(run_once, run, seqs, progress) if pool is not None else RunPool(1).map(run_once, run, seqs)
    return {str(s): out[i * n:(i + 1) * n] for i, s in enumerate(seeds)}


def _mean_ci(values) -> dict:
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if len(v) < 2:
        return {'mean': float(v.mean()) if len(v) else math.nan, 'lo': math.nan, 'hi': math.nan, 'n': len(v)}
    from scipy import stats
    half = float(stats.t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))
    return {'mean': float(v.mean()), 'lo': float(v.mean() - half), 'hi': float(v.mean() + half), 'n': len(v)}


# -- parts ------------------------------------------------------------------------------------------

def _roc(split: SeedSplit, sizes: Sizes, pool, progress) -> dict:
    rows = []
    for method in CFAR_METHODS:
        for pfa in PFA_GRID:
            run = ImagingRun('imaging_diver', sizes.sensor, sizes.scale, ROC_FRAMES, start=-1.0,
                             detector=_OFF + (('threshold.method', method), ('cfar.pfa', pfa)))
            runs = _runs(run, split.evaluation[:1], sizes.roc_runs, pool, progress)
            det = [r['detector'] for rs in runs.values() for r in rs]
            rows.append({'method': method, 'pfa': pfa, 'pd': _mean_ci([d['pd'] for d in det]),
                         'false_per_frame': _mean_ci([d['false_per_frame'] for d in det]), 'runs': len(det)})
    for seed_db in SEED_DB_GRID:
        run = ImagingRun('imaging_diver', sizes.sensor, sizes.scale, ROC_FRAMES, start=-1.0, methods=(), path='regions',
                         fls=(('structure.enabled', False), ('segment.seed_db', seed_db),
                              ('segment.grow_db', min(REGION_GROW_DB, seed_db))))
        runs = _runs(run, split.evaluation[:1], sizes.roc_runs, pool, progress)
        det = [r['detector'] for rs in runs.values() for r in rs]
        rows.append({'method': 'regions', 'seed_db': seed_db, 'pd': _mean_ci([d['pd'] for d in det]),
                     'false_per_frame': _mean_ci([d['false_per_frame'] for d in det]), 'runs': len(det)})
    return {'frames_per_run': ROC_FRAMES, 'scale': sizes.scale, 'seed': split.evaluation[0], 'rows': rows}


def _esc(split: SeedSplit, sizes: Sizes, pool, progress) -> dict:
    base = ImagingRun('imaging_empty', sizes.sensor, 1, sizes.esc_frames, sim=ESC_WINDOW, platform_speed=ESC_SPEED,
                      series=True, detector=(('structure.enabled', False),))
    # Calibration: the density ESC measures at the design scale on Rayleigh frames.
    cal = _runs(replace(base, frames=ESC_SWITCH, detector=base.detector + (('esc.enabled', False),)),
                split.calibration, sizes.calibration_runs, pool, progress)
    rho_d = float(np.mean([r['detector']['density'].mean() for rs in cal.values() for r in rs]))
    a, b = ESC_SCORED
    out: dict[str, Any] = {'rho_d': rho_d, 'switch_frame': ESC_SWITCH, 'scored_frames': [a, b],
                           'window': dict(ESC_WINDOW), 'platform_speed': ESC_SPEED, 'sets': {}}
    for on in (True, False):
        run = replace(base, clutter_switch=(ESC_SWITCH, 'k', 0.5),
                      detector=base.detector + (('esc.enabled', on), ('esc.desired_clutter_density', rho_d)))
        runs = _runs(run, split.evaluation, sizes.esc_runs, pool, progress)
        key = 'esc_on' if on else 'esc_off'
        for s, rs in runs.items():
            ratio = [float(r['detector']['density'][a:b].mean() / rho_d) for r in rs]
            before = [float(r['detector']['density'][ESC_SWITCH // 2:ESC_SWITCH].mean() / rho_d) for r in rs]
            scale = [float(r['detector']['scale'][a:b].mean()) for r in rs]
            out['sets'].setdefault(s, {})[key] = {'after': _mean_ci(ratio), 'before': _mean_ci(before),
                                                 'scale_after': _mean_ci(scale), 'per_run': per_run_values(ratio)}
    return out


def _static(split: SeedSplit, sizes: Sizes, pool, progress) -> dict:
    run = ImagingRun('imaging_empty', sizes.sensor, sizes.static_scale, sizes.static_frames)
    runs = _runs(run, split.evaluation, 1, pool, progress)
    per = {s: {'confirmed_tracks': rs[0]['ipda']['false_tracks'], 'minutes': rs[0]['ipda']['hours'] * 60.0,
               'false_per_frame': rs[0]['detector']['false_per_frame'], 'final_scale': rs[0]['detector']['final_scale']}
           for s, rs in runs.items()}
    return {'scale': sizes.static_scale, 'frames': sizes.static_frames, 'sets': per}


def _tracking_summary(rs: list[dict], method: str) -> dict:
    false = int(sum(r[method]['false_tracks'] for r in rs))
    hours = float(sum(r[method]['hours'] for r in rs))
    return {'cttr': _mean_ci([r[method]['cttr'] for r in rs]), 'gospa': _mean_ci([r[method]['gospa'] for r in rs]),
            'breaks': _mean_ci([r[method]['breaks'] for r in rs]),
            'duplicates': _mean_ci([r[method]['duplicates'] for r in rs]),
            'pd': _mean_ci([r['detector']['pd'] for r in rs]),
            'false_per_frame': _mean_ci([r['detector']['false_per_frame'] for r in rs]),
            'false_tracks': false, 'hours': hours,
            'false_per_hour': false / hours if hours else math.nan,
            'false_per_hour_upper95': poisson_upper(false, hours)}


#: How the diver part chooses rho_D (:func:`~.evidence.choose_smallest_within_one_se`). A smaller rho_D
#: lets fewer false detections through, so where CTTR cannot tell the values apart the one that risks
#: fewer false tracks wins.
DIVER_RULE = ('the smallest rho_D whose mean CTTR on the calibration runs lies within one standard error of '
              'the largest, among the rho_D with no false confirmed track there (the one-standard-error rule)')


def rho_grid(sensor: str) -> tuple[float, ...]:
    """The diver part's candidate rho_D of ``sensor`` [1/m^2]: :data:`RHO_FACTORS` times its preset's
    ``esc.desired_clutter_density``."""
    preset = front_end(sensor)[0].esc.desired_clutter_density
    return tuple(float(f * preset) for f in RHO_FACTORS)


def _diver(split: SeedSplit, sizes: Sizes, pool, progress) -> dict:
    base = ImagingRun('imaging_diver', sizes.sensor, sizes.scale, sizes.diver_frames)
    grid = rho_grid(sizes.sensor)
    cttrs, false = [], []
    for rho in grid:
        run = replace(base, detector=(('esc.desired_clutter_density', rho),))
        rs = [r for v in _runs(run, split.calibration, sizes.calibration_runs, pool, progress).values() for r in v]
        cttrs.append([r['ipda']['cttr'] for r in rs if math.isfinite(r['ipda']['cttr'])])
        false.append(int(sum(r['ipda']['false_tracks'] for r in rs)))
    rule = choose_smallest_within_one_se(grid, cttrs, [f == 0 for f in false])
    calibration = [{'rho_d': rho, 'cttr': m, 'cttr_se': se, 'false_tracks': f}
                   for rho, m, se, f in zip(grid, rule['means'], rule['ses'], false)]
    chosen = rule['value']
    run = replace(base, detector=(('esc.desired_clutter_density', chosen),))
    runs = _runs(run, split.evaluation, sizes.runs, pool, progress)
    held = read_back(chosen, [r['detector']['desired_density'] for rs in runs.values() for r in rs])
    sets = {s: _tracking_summary(rs, 'ipda') for s, rs in runs.items()}
    pooled = _tracking_summary([r for rs in runs.values() for r in rs], 'ipda')
    return {'scale': sizes.scale, 'frames': sizes.diver_frames or 'scenario (120 s)', 'rho_factors': list(RHO_FACTORS),
            'calibration': calibration,
            'rule': DIVER_RULE, 'cttr_bar': rule['bar'], 'rho_d': chosen, 'read_back': held, 'sets': sets,
            'pooled': pooled}


def _school(split: SeedSplit, sizes: Sizes, pool, progress) -> dict:
    methods = ('ipda', 'jipda')
    base = ImagingRun('imaging_school', sizes.sensor, sizes.scale, sizes.school_frames, methods=methods, detector=FISH)
    costs: dict[str, list[float]] = {m: [] for m in methods}
    for t_c in T_GRID:
        run = replace(base, confirm=tuple((m, t_c) for m in methods))
        rs = [r for v in _runs(run, split.calibration, sizes.calibration_runs, pool, progress).values() for r in v]
        for m in methods:
            costs[m].append(float(np.mean([r[m]['gospa'] for r in rs])))
    choice = {m: choose_minimum(T_GRID, costs[m]) for m in methods}
    run = replace(base, confirm=tuple((m, choice[m]['value']) for m in methods))
    runs = _runs(run, split.evaluation, sizes.runs, pool, progress)
    metrics = ('gospa', 'cttr', 'breaks')
    corr = Correction(intervals=len(metrics))
    comparisons = []
    for metric in metrics:
        samples = {s: {m: [r[m][metric] for r in rs] for m in methods} for s, rs in runs.items()}
        row = compare(samples, 'jipda', 'ipda', corr, heavy_tailed=metric == 'gospa')
        row['metric'] = metric
        comparisons.append(row)
    gos = comparisons[0]['seeds']
    lead = all(gos[s]['high'] is not None and gos[s]['high'] < 0 for s in gos)
    return {'scale': sizes.scale, 'frames': sizes.school_frames or 'scenario', 'detector': dict(FISH), 'costs': costs,
            'choice': choice, 'read_back': {m: read_back(choice[m]['value'], [r[m]['confirm'] for rs in runs.values()
                                                                               for r in rs]) for m in methods},
            'methods': {m: _tracking_summary([r for rs in runs.values() for r in rs], m) for m in methods},
            'correction': corr.describe(), 'comparisons': comparisons, 'jipda_lead_on_both_sets': lead}


_PART_FUNCS = {'roc': _roc, 'esc': _esc, 'static': _static, 'diver': _diver, 'school': _school}


def run_table(split: SeedSplit, sizes: Sizes, parts=PARTS, pool: RunPool | None = None,
              progress: bool | None = None) -> dict:
    """Every part of ``parts`` (module docstring); JSON-ready."""
    prog = None
    out: dict[str, Any] = {'sensor': sizes.sensor, 'seeds': split.describe(), 'sizes': sizes.describe(),
                           'gospa': GOSPA.describe(), 'gate': GATE, 'clearance': CLEARANCE, 'parts': list(parts)}
    for part in parts:
        out[part] = {**_PART_FUNCS[part](split, sizes, pool, prog), 'seeds': split.describe()}
    return with_comparisons(out)


def with_comparisons(result: dict) -> dict:
    """``result`` with the paired comparisons of its parts where every results table keeps them
    (``correction``, ``cells``: the school's JIPDA against IPDA)."""
    school = result.get('school')
    result['correction'] = school['correction'] if school else Correction(intervals=1).describe()
    result['cells'] = [{'cell': 'school', 'comparisons': school['comparisons']}] if school else []
    return result


# -- the docs table ---------------------------------------------------------------------------------

def _ci(d: dict, digits: int = 3) -> str:
    if not math.isfinite(d.get('lo', math.nan)):
        return f'{d["mean"]:.{digits}g}'
    return f'{d["mean"]:.{digits}g} [{d["lo"]:.{digits}g}, {d["hi"]:.{digits}g}]'


def _own_seeds(part: dict, seeds: dict) -> str:
    """For a part run on other seeds than the table's (parts of a table run by separate commands):
    its seeds, to go into its heading."""
    own = part.get('seeds')
    if not own or all(own[k] == seeds[k] for k in ('calibration', 'evaluation')):
        return ''
    return (f'; calibration seeds {", ".join(map(str, own["calibration"]))}, evaluation seeds '
            f'{" / ".join(map(str, own["evaluation"]))}')


def format_table(result: dict) -> str:
    """The docs/results tables (markdown) of :func:`run_table`'s result; a part run on other seeds
    than the table's names them."""
    lines: list[str] = []
    seeds = result['seeds']
    g = result['gospa']
    lines.append(f'Head {result.get("sensor", SENSOR)}. Calibration seeds {", ".join(map(str, seeds["calibration"]))}; '
                 f'evaluation seeds '
                 f'{" / ".join(map(str, seeds["evaluation"]))}. Intervals: 95 % t intervals over runs. GOSPA c = '
                 f'{g["c"]:g} m, p = {g["p"]:g}, alpha = {g["alpha"]:g}; tracked within {result["gate"]:g} m; a '
                 f'confirmed track never within {result["clearance"]:g} m of a target is false.')
    if 'roc' in result:
        r = result['roc']
        lines += ['', f'**Detection** (`imaging_diver`, frames reduced {r["scale"]}x, {r["frames_per_run"]} frames '
                  f'per run from a random time, ESC and structure rejection off, seed {r["seed"]}):', '',
                  '| front end | operating point | runs | P_D of the diver | false detections / frame |',
                  '|---|---|---|---|---|']
        for row in r['rows']:
            point = (f'seed {row["seed_db"]:g} dB' if row['method'] == 'regions' else f'design P_fa {row["pfa"]:g}')
            name = 'FLS regions' if row['method'] == 'regions' else f'{row["method"].upper()}-CFAR'
            lines.append(f'| {name} | {point} | {row["runs"]} | {_ci(row["pd"])} | {_ci(row["false_per_frame"])} |')
    if 'esc' in result:
        e = result['esc']
        lines += ['', f'**ESC under a change of clutter shape** (Rayleigh, then K shape 0.5 from frame '
                  f'{e["switch_frame"]}; a {e["window"]["imaging.n_beams"]}-beam, {e["window"]["imaging.n_bins"]}-bin '
                  f'window of the head moving at {e["platform_speed"]:g} m/s; rho_D = {e["rho_d"]:.3g} /m^2 chosen on '
                  f'the calibration runs): density over rho_D, mean of frames {e["scored_frames"][0]}-'
                  f'{e["scored_frames"][1]} (criterion: 0.8-1.2 with ESC on).', '',
                  '| seed set | ESC on: after the switch | before the switch | ESC off (CA alone): after | runs |',
                  '|---|---|---|---|---|']
        for s, v in e['sets'].items():
            lines.append(f'| {s} | {_ci(v["esc_on"]["after"])} | {_ci(v["esc_on"]["before"])} | '
                         f'{_ci(v["esc_off"]["after"])} | {v["esc_on"]["after"]["n"]} |')
    if 'static' in result:
        st = result['static']
        size = 'full frames' if st['scale'] == 1 else f'frames reduced {st["scale"]}x'
        lines += ['', f'**Static empty scene, frozen speckle** (`imaging_empty`, {size}{_own_seeds(st, seeds)}):', '',
                  '| seed | minutes | confirmed tracks | false detections / frame |', '|---|---|---|---|']
        for s, v in st['sets'].items():
            lines.append(f'| {s} | {v["minutes"]:.1f} | {v["confirmed_tracks"]} | {v["false_per_frame"]:.3g} |')
    if 'diver' in result:
        d = result['diver']
        lines += ['', f'**Diver** (`imaging_diver`, frames reduced {d["scale"]}x{_own_seeds(d, seeds)}; '
                  f'rho_D = {d["rho_d"]:g} /m^2 '
                  f'chosen on the calibration runs: {d["rule"]}):', '',
                  '| seed set | CTTR | false confirmed tracks (hours) | per hour, 95 % upper bound | breaks / target | '
                  'duplicates | GOSPA [m] | P_D | false detections / frame |', '|---|---|---|---|---|---|---|---|---|']
        for s, v in list(d['sets'].items()) + [('pooled', d['pooled'])]:
            lines.append(f'| {s} | {_ci(v["cttr"])} | {v["false_tracks"]} ({v["hours"]:.2f}) | '
                         f'{v["false_per_hour_upper95"]:.3g} | {_ci(v["breaks"])} | {_ci(v["duplicates"])} | '
                         f'{_ci(v["gospa"])} | {_ci(v["pd"])} | {_ci(v["false_per_frame"])} |')
        cal = '; '.join(f'{c["rho_d"]:g}: CTTR {c["cttr"]:.4f}'
                        + (f' ± {c["cttr_se"]:.4f}' if c.get('cttr_se') is not None else '')
                        + f', {c["false_tracks"]} false' for c in d['calibration'])
        lines += ['', f'Calibration runs by rho_D [/m^2] (mean CTTR ± standard error, false confirmed tracks): {cal}.']
    if 'school' in result:
        sc = result['school']
        corr = Correction(sc['correction']['intervals'], sc['correction']['family_level'])
        fish = ', '.join(f'{k} {v:g}' for k, v in sc.get('detector', {'cells.target_size': 0.3}).items())
        lines += ['', f'**Crossing school** (`imaging_school`, frames reduced {sc["scale"]}x, set for fish: {fish}; '
                  f'T_c of least calibration GOSPA: IPDA {sc["choice"]["ipda"]["value"]:g}, JIPDA '
                  f'{sc["choice"]["jipda"]["value"]:g}). JIPDA ahead on GOSPA on both evaluation seed sets: '
                  f'{"yes" if sc["jipda_lead_on_both_sets"] else "no"}. P_D of a fish '
                  f'{_ci(sc["methods"]["ipda"]["pd"])}; CTTR IPDA {_ci(sc["methods"]["ipda"]["cttr"])}, JIPDA '
                  f'{_ci(sc["methods"]["jipda"]["cttr"])}; GOSPA IPDA {_ci(sc["methods"]["ipda"]["gospa"])}, JIPDA '
                  f'{_ci(sc["methods"]["jipda"]["gospa"])} m.', '',
                  f'Paired per-run differences JIPDA − IPDA; {corr.text()}; {AGREEMENT_RULE}.', '']
        rows = [('school', k['metric'], k) for k in sc['comparisons']]
        lines += format_comparisons(rows, [str(s) for s in seeds['evaluation']])
    return '\n'.join(lines)

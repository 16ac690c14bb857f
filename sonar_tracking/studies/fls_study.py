"""The FLS paper's tracking study (§5): Table 5 situations and the sea trial, by method, Monte Carlo.

One run simulates a situation's frames once (:func:`~.fls_frames.simulate_tracking_frames`) and
hands the *same* frames to every method (common random numbers): the GPF with adaptive (``af``:
eq. 18 plus the crossing switch, the default; ``af18``: eq. 18 alone, ``fusion.switch: cues``),
multiplicative (``mf``) or weighted (``wf``) fusion, the SIR particle filter (``pf``, on the same
cues with multiplicative fusion) and the EKF on the regions (``ekf``). Every particle method also
starts from the same random stream of the run, so methods that take the same decisions draw the
same particles: AF differs from WF only after a frame where it chose MF, and the comparison
measures the fusion rule, not the draws (with a stream per method, the draws alone move a 30-run
mean CLE by up to 0.25 m on situation 9: ``docs/experiments/2026-11-21-fls-gpf-study.md``).

Scoring, per target and frame, against the target's state as imaged (:mod:`.fls_frames`), of every
track, or with ``score_confirmed`` of the confirmed tracks only (what the tracker reports as
confirmed); ``confirm_by_method`` builds each method's tracker with its own ``birth.confirm_hits``
(each run records the value its tracker holds), and ``gospa`` records per frame the GOSPA between
the targets and the scored tracks:

* **Owner.** A target is followed by the track that first came within ``gate`` metres of it (one
  track per target, chosen jointly by least distance among tracks no other target owns); it keeps
  that owner while the track exists, and takes a new one (another identity) only when its owner
  has ended.
* **CLE** (eq. 19): distance from the owner's estimate to the target; undefined (NaN) while the
  target has no owner. ``cle_mean`` averages the defined values (the paper's curves).
* **Lost frame**: a frame where the target has no owner or its owner is farther than ``gate``.
  ``cle_capped_mean`` counts such frames as ``gate`` and caps the CLE there (an OSPA-like
  figure that a method cannot improve by dropping tracks).
* **Corrections**: per method, the track-frames corrected by the image (the particles weighed by
  the window features, eqs. 13-18), by re-finding a segmented region (a Kalman update on its
  centroid; every EKF correction is one), and neither (coasting).
* **Identity kept through a crossing** (two targets whose true paths come within
  ``cross_distance`` of each other): the owner of each target in the last frame before they
  come that close is, in most frames after they have parted again, within ``gate`` of the same
  target and nearer to it than to the other one. A run keeps identity when every target that had
  an owner before the crossing does; a run where no target had one says nothing about identity
  and is left out of the rate (``identity_runs`` counts the runs that count).

Why the methods differ so little, in short: the window cues of eq. (13) concentrate the particles
weakly, so the tracker accepts its own image update in only a third to a half of the frames and is
otherwise corrected by re-finding a segmented region (the centroids the EKF uses). The measurements
behind this, the tuning of ``min_std``, ``lost.max_time`` and the thresholds ``T_i``, the ideas
tried and not kept, and the 1000-run criteria are dated entries in ``docs/experiments/``
(``2026-11-21-fls-gpf-study.md``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.fls import FlsConfig
from sonar_tracking.core.gpf import EkfConfig, EkfTracker, GpfConfig, GpfTracker
from sonar_tracking.core.gpf.management import gated_assignment
from sonar_tracking.sim.simulator import child_seeds
from sonar_tracking.studies.evidence import GospaSpec
from sonar_tracking.studies.fls_frames import TrackingFrame, simulate_tracking_frames
from sonar_tracking.studies.metrics import center_location_error, paired_difference

__all__ = ['METHODS', 'FlsStudy', 'parse_methods', 'situation_scenario', 'run_methods', 'score_run', 'run_once',
           'summarise', 'run_cle', 'paired_difference', 'cue_statistics', 'crossing_window', 'reliability_samples',
           'reliability_statistics', 'switch_thresholds']

#: Methods of the study, in the order of Figures 13, 16 and 19.
METHODS = ('af', 'af18', 'mf', 'wf', 'pf', 'ekf')


def parse_methods(text: str) -> tuple[str, ...]:
    """``'af,mf,ekf'`` -> methods; ValueError names the unknown ones."""
    out = tuple(m.strip().lower() for m in text.split(',') if m.strip())
    bad = [m for m in out if m not in METHODS]
    if bad or not out:
        raise ValueError(f'unknown method(s) {bad or text!r}; choose from {",".join(METHODS)}')
    if len(set(out)) != len(out):
        raise ValueError(f'methods {text!r} names one twice')
    return out


def situation_scenario(situation: int | str) -> str:
    """Simulator scenario of a Table 5 situation (1-14) or ``'sea-trial'``."""
    if situation in ('sea-trial', 'sea_trial'):
        return 'sea_trial'
    n = int(situation)
    if not 1 <= n <= 14:
        raise ValueError(f'situation {situation} is not in Table 5 (1-14)')
    return f'fls{n}'


@dataclass(frozen=True)
class FlsStudy:
    """One study: a situation, the methods, the tracker settings and the scoring distances."""

    scenario: str
    methods: tuple[str, ...] = METHODS
    config: GpfConfig = GpfConfig()
    ekf: EkfConfig = EkfConfig()
    fls: FlsConfig = FlsConfig()
    preset: str = ''
    gate: float = 1.5
    cross_distance: float = 2.0
    sim_overrides: tuple[tuple[str, object], ...] = ()
    confirm_by_method: tuple[tuple[str, int], ...] = ()   # (method, birth.confirm_hits) run inside the run
    score_confirmed: bool = False         # score the confirmed tracks only (else every track)
    gospa: GospaSpec | None = None        # also record GOSPA per frame (targets against the scored tracks)


def _tracker(study: FlsStudy, method: str, rng: np.random.Generator):
    own = dict(study.confirm_by_method)
    base = study.config
    if method in own:
        base = base.from_flat({'birth.confirm_hits': int(own[method])}, base=base)
    if method == 'ekf':
        return EkfTracker(base, study.ekf)
    flat = {'fusion.mode': {'pf': 'mf', 'af18': 'af'}.get(method, method)}
    if method == 'af18':
        flat['fusion.switch'] = 'cues'
    cfg = study.config.from_flat(flat, base=base)
    return GpfTracker(cfg, rng, method='sir' if method == 'pf' else 'gpf', feature_config=study.fls.features)


def run_methods(study: FlsStudy, frames: list[TrackingFrame], seed: np.random.SeedSequence,
                corrections: dict | None = None, held: dict | None = None) -> dict[str, list]:
    """Every method's track records per frame on the same frames; ``corrections`` (when given)
    receives per method the track-frames corrected by the image, by a region, and coasting; ``held``
    (when given) the ``birth.confirm_hits`` each method's tracker holds, read from its configuration."""
    out = {}
    for method in study.methods:
        rng = np.random.default_rng(seed)     # the same stream for every method: see module docstring
        tracker = _tracker(study, method, rng)
        if held is not None:
            held[method] = int(tracker.config.birth.confirm_hits)
        per_frame, counts = [], np.zeros(3, dtype=np.int64)
        for tf in frames:
            f = tf.frame
            if method == 'ekf':
                per_frame.append(tracker.step(f.stamp, f.regions, f.sensor_pose))
            else:
                per_frame.append(tracker.step(f.stamp, f.image, f.grid, f.regions, f.sensor_pose))
            rep = tracker.report
            counts += _corrections(rep.seen, rep.missed, rep.reseeded, method == 'ekf')
        out[method] = per_frame
        if corrections is not None:
            corrections[method] = counts
    return out


def _corrections(seen: int, missed: int, reseeded: int, regions_only: bool) -> tuple[int, int, int]:
    """``(image, region, coasting)`` track counts of one frame from a tracker's report: a particle
    track seen was corrected by the image, one re-found by a region; every EKF update is a region."""
    if regions_only:
        return 0, seen, missed
    return seen, reseeded, missed - reseeded


def crossing_window(frames: list[TrackingFrame], distance: float) -> tuple[int, int] | None:
    """``(last frame before, first frame after)`` two targets come within ``distance``; None when
    no two targets do (or they never part again, or are close from the start)."""
    if not frames or frames[0].truth.shape[0] < 2:
        return None
    xy = np.stack([tf.truth[:, :2] for tf in frames])                           # (F, G, 2)
    d = np.linalg.norm(xy[:, :, None, :] - xy[:, None, :, :], axis=-1)
    g = xy.shape[1]
    close = np.array([np.min(d[k][~np.eye(g, dtype=bool)]) < distance for k in range(len(frames))])
    idx = np.flatnonzero(close)
    if idx.size == 0 or idx[0] == 0 or idx[-1] == len(frames) - 1:
        return None
    return int(idx[0] - 1), int(idx[-1] + 1)


def score_run(frames: list[TrackingFrame], records: list[np.ndarray], gate: float, cross_distance: float) -> dict:
    """CLE, lost frames, identity changes and identity through the crossing of one method's tracks."""
    n_f, g = len(frames), frames[0].truth.shape[0] if frames else 0
    cle = np.full((g, n_f), np.nan)
    owner_id = np.zeros((g, n_f), np.int64)          # 0 = no owner
    owner: list[int | None] = [None] * g
    acquisitions = np.zeros(g, np.int64)
    for k, (tf, rec) in enumerate(zip(frames, records)):
        ids = rec['track_id'].astype(np.int64)
        est = np.column_stack([rec['x'], rec['y']]) if len(rec) else np.zeros((0, 2))
        where = {int(i): j for j, i in enumerate(ids)}
        for t in range(g):
            if owner[t] is not None and owner[t] not in where:
                owner[t] = None
        free_targets = [t for t in range(g) if owner[t] is None]
        taken = {o for o in owner if o is not None}
        free_tracks = [j for j in range(len(ids)) if int(ids[j]) not in taken]
        if free_targets and free_tracks:
            d = np.linalg.norm(tf.truth[free_targets, None, :2] - est[None, free_tracks], axis=-1)
            for r, c in gated_assignment(d, gate):
                owner[free_targets[r]] = int(ids[free_tracks[c]])
                acquisitions[free_targets[r]] += 1
        for t in range(g):
            if owner[t] is not None:
                j = where[owner[t]]
                cle[t, k] = center_location_error(est[j], tf.truth[t, :2])
                owner_id[t, k] = owner[t]
    lost = np.isnan(cle) | (cle > gate)
    capped = np.where(lost, gate, np.minimum(cle, gate))
    out = {'cle': cle, 'lost': lost, 'capped': capped, 'acquisitions': acquisitions, 'identity': None}
    window = crossing_window(frames, cross_distance)
    if window is not None and g >= 2:
        before, after = window
        kept = np.full(g, np.nan)
        for t in range(g):
            tid = owner_id[t, before]
            if tid == 0:
                continue                       # no track before the crossing: nothing to keep
            good = 0
            post = range(after, n_f)
            for k in post:
                rec = records[k]
                hit = np.flatnonzero(rec['track_id'] == tid)
                if hit.size == 0:
                    continue
                p = np.array([rec['x'][hit[0]], rec['y'][hit[0]]])
                dist = np.linalg.norm(frames[k].truth[:, :2] - p, axis=1)
                if dist[t] < gate and dist[t] <= dist.min():
                    good += 1
            kept[t] = float(good > 0.5 * len(post))
        out['identity'] = kept
    return out


def run_once(study: FlsStudy, seed: np.random.SeedSequence) -> dict:
    """One Monte Carlo run: simulate, track with every method, score (module docstring)."""
    sim_seed, track_seed = child_seeds(seed, 2)  # not seed.spawn: that changes the caller's sequence
    frames = simulate_tracking_frames(study.scenario, sim_seed, study.fls, study.preset, **dict(study.sim_overrides))
    corrections: dict = {}
    held: dict = {}
    tracks = run_methods(study, frames, track_seed, corrections, held)
    scored = ({m: [r[r['confirmed'] != 0] for r in recs] for m, recs in tracks.items()} if study.score_confirmed
              else tracks)
    scores = {m: score_run(frames, recs, study.gate, study.cross_distance) for m, recs in scored.items()}
    truth = np.stack([tf.truth for tf in frames]) if frames else np.zeros((0, 0, 4))
    est = {m: [np.column_stack([r['track_id'], r['x'], r['y']]) for r in recs] for m, recs in tracks.items()}
    out = {'stamps': np.array([tf.stamp for tf in frames]), 'ids': frames[0].ids if frames else np.zeros(0),
           'truth': truth, 'scores': scores, 'tracks': est, 'corrections': corrections, 'confirm': held}
    if study.gospa is not None:
        out['gospa'] = {m: np.array([study.gospa(tf.truth[:, :2], np.column_stack([r['x'], r['y']])).distance
                                     for tf, r in zip(frames, recs)]) for m, recs in scored.items()}
    return out


def summarise(study: FlsStudy, runs: list[dict]) -> dict:
    """JSON-ready per-method results over runs: ``cle_mean`` and ``lost_frames`` per target, ``cle``
    per target per frame (mean over the runs where defined), and the rest (module docstring)."""
    out, run_means = {}, {}
    for m in study.methods:
        cle = np.stack([r['scores'][m]['cle'] for r in runs])             # (R, G, F)
        lost = np.stack([r['scores'][m]['lost'] for r in runs])
        capped = np.stack([r['scores'][m]['capped'] for r in runs])
        acq = np.stack([r['scores'][m]['acquisitions'] for r in runs])
        per_frame = _nanmean(cle, axis=0)
        res = {
            'cle_mean': [_finite(_nanmean(cle[:, t])) for t in range(cle.shape[1])],
            'cle': [[_finite(v) for v in row] for row in per_frame],
            'lost_frames': [float(lost[:, t].sum(axis=1).mean()) for t in range(cle.shape[1])],
            'cle_capped_mean': [float(capped[:, t].mean()) for t in range(cle.shape[1])],
            'identity_changes': [float((acq[:, t] - 1).clip(0).mean()) for t in range(cle.shape[1])],
            'runs_never_tracked': [int((acq[:, t] == 0).sum()) for t in range(cle.shape[1])],
        }
        image, region, coast = np.sum([r['corrections'][m] for r in runs], axis=0).tolist()
        res['corrections'] = {'image': image, 'region': region, 'coasting': coast,
                              'image_share': image / (image + region) if image + region else None}
        run_means[m] = np.array([run_cle(c) for c in cle])
        res['cle_run'] = [_finite(v) for v in run_means[m]]
        ident = [r['scores'][m]['identity'] for r in runs]
        if ident and all(i is not None for i in ident):
            kept = np.stack(ident)                                          # (R, G): 1, 0 or NaN
            counted = ~np.isnan(kept).all(axis=1)
            run_kept = np.nan_to_num(kept, nan=1.0).all(axis=1)
            res['identity_kept_rate'] = float(run_kept[counted].mean()) if counted.any() else None
            res['identity_runs'] = int(counted.sum())
            res['identity_kept_rate_per_target'] = [_finite(_nanmean(kept[:, t])) for t in range(kept.shape[1])]
        out[m] = res
    first = study.methods[0]
    for m in study.methods[1:]:
        out[m]['paired_with_first'] = {'first': first, **paired_difference(run_means[first], run_means[m])}
    return out


def run_cle(cle: np.ndarray) -> float:
    """One run's mean CLE from its ``cle (G, F)``: the mean over targets of each target's mean over
    the frames where it is defined (NaN when no target has any)."""
    per_target = _nanmean(np.asarray(cle, dtype=np.float64), axis=1)
    return float(_nanmean(per_target))


def _nanmean(a: np.ndarray, axis=None):
    """Mean over the finite entries (NaN where there are none), without numpy's warning."""
    ok = ~np.isnan(a)
    n = ok.sum(axis=axis)
    total = np.where(ok, a, 0.0).sum(axis=axis)
    return np.where(n > 0, total / np.maximum(n, 1), np.nan)


def _finite(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def cue_statistics(frames: list[TrackingFrame], config: FlsConfig | None = None, window: float = 1.1) -> dict:
    """Calibration of :data:`sonar_tracking.core.gpf.cues.CUE_SPECS`: for every cue feature, the
    median magnitude on targets (``ref``) and the root-mean-square change of its transformed value
    at a target's imaged centre between consecutive frames (``sigma``)."""
    from sonar_tracking.core.fls.windows import WindowImage
    from sonar_tracking.core.gpf.cues import CUE_SPECS, CueSpec, window_pixels
    config = config or FlsConfig()
    feats = sorted(CUE_SPECS)
    values: dict[int, list[np.ndarray]] = {}
    for tf in frames:
        f = tf.frame
        wi = WindowImage(f.image, config.features)
        r, c = f.grid.point_to_pixel(tf.truth[:, 0], tf.truth[:, 1])
        v = wi.features(np.rint(r).astype(np.int64), np.rint(c).astype(np.int64),
                        window_pixels(window, f.grid.resolution), feats)
        for g, tid in enumerate(tf.ids):
            values.setdefault(int(tid), []).append(v[g])
    out = {}
    for i, n in enumerate(feats):
        spec = CUE_SPECS[n]
        raw = np.concatenate([np.array(s)[:, i] for s in values.values()])
        ref = float(np.median(np.abs(raw))) if spec.transform == 'asinh' else spec.ref
        probe = CueSpec(n, spec.transform, 1.0, ref)
        diffs = np.concatenate([np.diff(probe.apply(np.array(s)[:, i])) for s in values.values()])
        out[n] = {'transform': spec.transform, 'ref': ref, 'sigma': float(np.sqrt(np.mean(diffs ** 2)))
                  if diffs.size else math.nan}
    return out


def reliability_samples(frames_by_run: list[list[TrackingFrame]], rng: np.random.Generator,
                        config: GpfConfig | None = None, prior_std: float = 0.4, particles: int = 300
                        ) -> tuple[tuple[int, ...], np.ndarray]:
    """Every cue feature's reliability ``Delta_0 / Delta_i`` (:func:`sonar_tracking.core.gpf.fusion.fuse`)
    on healthy tracks: particles drawn around a target's imaged centre with ``prior_std`` per axis
    (their mean off by a third of that), the template its window in the previous frame where
    segmentation found it, on frames where segmentation finds it again; with the likelihood of
    ``config`` (``cues.alpha``). Returns the features and the samples ``(N, features)``, one row a
    track and frame, so the cues' joint behaviour is kept."""
    from sonar_tracking.core.gpf.cues import CUE_SPECS, CueModel
    from sonar_tracking.core.gpf.fusion import cue_spreads, cue_weights
    config = config or GpfConfig()
    feats = tuple(sorted(CUE_SPECS))
    cues = CueModel(feats, config.cues.window, config.cues.alpha)
    rows: list[np.ndarray] = []
    for frames in frames_by_run:
        last: dict[int, np.ndarray] = {}
        for tf in frames:
            f = tf.frame
            wi = cues.prepare(f.image)
            xy = np.column_stack([f.regions['x'], f.regions['y']]) if len(f.regions) else np.zeros((0, 2))
            for g, tid in enumerate(tf.ids):
                t = tf.truth[g, :2]
                if len(xy) == 0 or np.hypot(*(xy - t).T).min() > 0.6:
                    continue
                here = cues.values(wi, f.grid, t[None])[:, 0]
                template = last.get(int(tid))
                last[int(tid)] = here
                if template is None:
                    continue
                centre = t + rng.normal(0.0, prior_std / 3.0, 2)
                pos = centre + rng.normal(0.0, prior_std, (particles, 2))
                log_p = cues.log_likelihoods(cues.distances2(cues.values(wi, f.grid, pos), template))
                k = len(pos)
                prior = cue_spreads(pos, np.full((1, k), 1.0 / k))[0]
                rows.append(prior / cue_spreads(pos, cue_weights(log_p)))
    return feats, np.array(rows).reshape(-1, len(feats))


def reliability_statistics(frames_by_run: list[list[TrackingFrame]], rng: np.random.Generator,
                           config: GpfConfig | None = None, prior_std: float = 0.4, particles: int = 300,
                           quantile: float = 25.0) -> dict[int, float]:
    """The ``quantile`` percentile of every cue feature's reliability on healthy tracks
    (:func:`reliability_samples`): below its lower quartile a cue does worse than in 3 of 4
    healthy frames."""
    feats, samples = reliability_samples(frames_by_run, rng, config, prior_std, particles)
    if not len(samples):
        return {n: math.nan for n in feats}
    return {n: float(np.percentile(samples[:, i], quantile)) for i, n in enumerate(feats)}


def switch_thresholds(samples: np.ndarray, healthy_mf: float = 0.75) -> tuple[np.ndarray, float]:
    """Thresholds ``T_i`` of eq. (18) for a cue set, from reliability samples ``(N, m)`` of those
    cues on healthy tracks (:func:`reliability_samples`): every cue's threshold is the same
    percentile ``p`` of its own samples, with ``p`` chosen so that in a fraction ``healthy_mf`` of
    the healthy samples every cue is above its threshold (adaptive fusion then uses MF there, and
    WF in the rest, the frames worse than that share of healthy ones). Returns ``(T (m,), p)``."""
    s = np.asarray(samples, dtype=np.float64)
    if s.ndim != 2 or not len(s):
        raise ValueError('switch_thresholds needs reliability samples (N, m) with N >= 1')

    def rate(p: float) -> tuple[np.ndarray, float]:
        t = np.percentile(s, p, axis=0)
        return t, float(np.mean(np.all(s > t, axis=1)))

    lo, hi = 0.0, 100.0
    for _ in range(40):               # rate(p) falls as p rises: bisection
        mid = 0.5 * (lo + hi)
        if rate(mid)[1] >= healthy_mf:
            lo = mid
        else:
            hi = mid
    return rate(lo)[0], lo

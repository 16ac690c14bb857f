"""The IMM-IPDA multi-target tracker (ESC paper §2.4): wires the parts together, scan by scan.

Each track is an independent IMM-IPDA (Musicki & Suvorova's IMM-IPDA as summarised by the
paper): interaction (eqs. 17-20), prediction (22-23) and existence prediction (24), gating
(25-27), likelihoods (28-29), update (30-40) and combination (41-42); track management as in
:mod:`~sonar_tracking.core.tracking.management`. Each scan is a handful of calls over all
tracks, modes and validated pairs at once: compiled kernels (:mod:`~sonar_tracking.core.jit`) for the
per-track arithmetic, numpy for the rest; no Python loop runs over tracks or measurements.

Input handling of :meth:`ImmIpdaTracker.step`:

* measurement rows with a non-finite position, a covariance that is not finite, symmetric and
  positive definite, or a clutter density that is not finite and positive are dropped; the
  rest of the scan is used. :attr:`ImmIpdaTracker.report` lists the dropped rows with reasons;
* a scan with the same stamp as the previous one is dropped whole (``report.duplicate_stamp``)
  and the previous output is returned again;
* a scan stamped before the previous one raises :class:`~sonar_tracking.core.timeline.TimeWentBack`
  and changes nothing: the caller decides whether it is late (drop it) or a new recording
  (:meth:`ImmIpdaTracker.reset`, then step again);
* a scan more than ``track.max_gap`` after the previous one resets the tracker: every track is
  removed, the new scan is processed as a first scan and ``report.reset`` says why. Track ids keep
  counting, so an id is never reused within the tracker's life (ids are ``uint32``; after 2^32
  starts they wrap, skipping ids still in use).

The output never holds a NaN: a track whose estimate stops being finite is removed
(``report.dropped_numerical``).

Work and memory per scan are bounded for any input (see :mod:`~sonar_tracking.core.tracking.management`
for the rules): at most ``init.max_per_scan`` tracks start per scan, at most ``track.max_tracks``
tracks are kept, at most ``track.max_pairs`` candidate pairs are formed, and they are processed in
chunks of at most ``_CHUNK_PAIRS`` (tracks are independent IPDAs, so chunking changes no result):
the per-pair arrays never exceed a fixed size.

Association (``association.method``, not in the paper): ``ipda`` (default) as above; ``jipda``
makes tracks that share validated detections compete for them (IMM-JIPDA,
:mod:`~sonar_tracking.core.tracking.jipda`): every chunk is gated first and the JIPDA factor of
each pair found over the whole scan's clusters (one scalar per pair), then each chunk is updated
by the same IPDA update with the pair's clutter density divided by its factor. Exact clusters have
at most ``association.max_cluster`` tracks, so the extra work per scan stays bounded.

Evidence of correlated scans (``existence.decorrelation_time`` tau > 0, not in the paper). Eq. (40)
takes every scan as independent evidence: its clutter a fresh Poisson draw, its detection of the
target a fresh Bernoulli one. An imaging sonar at 10-40 frames a second repeats much of one draw
over several frames: speckle of a still scene is frozen (the same peak crosses the threshold frame
after frame), and a target's aspect, and with it whether it is detected, changes over a fraction of
a second, so misses come in runs. Counted frame by frame (P_D 0.8 at 20 frames a second), a peak
seen in three frames makes a track almost certain, and a target missed for 0.4 s almost certainly
gone. With tau, a scan ``dt`` after the previous one enters the existence update with the likelihood
ratio of eq. (33) raised to ``min(1, dt / tau)``: the frames of one second weigh as ``1 / tau``
independent scans whatever the frame rate (for scans tau or more apart, as the paper's scanning
sonar, nothing changes). Only the existence is weighted; the state, mode and association updates are
those of the paper.

Coverage (optional, not in the paper): ``step(..., coverage=...)`` takes the polar window the
scan covered (:class:`~sonar_tracking.core.tracking.coverage.Coverage`); a track whose estimate
has stayed outside the windows of successive scans for ``track.outside_time`` seconds ends
(``report.left_coverage``). Scans without a window leave the clock as it is.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from sonar_tracking.core.records import TRACK_DTYPE
from sonar_tracking.core.timeline import check_forward
from sonar_tracking.core.tracking.config import MODE_NAMES, TrackerConfig
from sonar_tracking.core.tracking.coverage import Coverage
from sonar_tracking.core.tracking.errors import TrackingInputError
from sonar_tracking.core.tracking.gating import BoxSearch, gate_boxes, gate_pairs, gate_threshold
from sonar_tracking.core.tracking.imm import combine, interaction
from sonar_tracking.core.tracking.ipda import ipda_update
from sonar_tracking.core.tracking.jipda import association_factors, pair_likelihoods
from sonar_tracking.core.tracking.kalman import predict
from sonar_tracking.core.tracking.management import (
    assess_tracks,
    birth_measurements,
    duplicate_tracks,
    excess_tracks,
    initial_covariance,
    pair_budget,
    renew_tracks,
    unused_measurements,
)
from sonar_tracking.core.tracking.markov import mode_transition_matrix, predict_existence, update_existence
from sonar_tracking.core.tracking.measurements import Rejection, as_measurements, check_measurements
from sonar_tracking.core.tracking.motion import ConstantTurn, ConstantVelocity, MotionModel
from sonar_tracking.core.tracking.noise import white_noise_acceleration

__all__ = ['Mode', 'modes_from_config', 'StepReport', 'ImmIpdaTracker']

_ID_SPACE = 2 ** 32
# Most candidate pairs gated and updated at once (bounds the per-pair arrays, ~1 kB per pair).
_CHUNK_PAIRS = 1 << 16


@dataclass(frozen=True)
class Mode:
    """One IMM mode: a motion model and the PSD ``q`` of its white-noise acceleration."""

    name: str
    model: MotionModel
    noise: float


def modes_from_config(config: TrackerConfig) -> tuple[Mode, ...]:
    """The modes ``config.imm.models`` names, in that order (cv: eq. 3, ccw/cw: eq. 4 with +/-Omega)."""
    rates = config.turn_rates()
    out = []
    for name in config.imm.mode_names:
        if name == 'cv':
            out.append(Mode('cv', ConstantVelocity(2), config.imm.noise_cv))
        else:
            out.append(Mode(name, ConstantTurn(rates[name], name=name), config.imm.noise_ctr))
    return tuple(out)


@dataclass
class StepReport:
    """What happened in the last :meth:`ImmIpdaTracker.step`, for logs and diagnostics."""

    t: float = math.nan
    n_measurements: int = 0
    rejected: list[Rejection] = field(default_factory=list)
    duplicate_stamp: bool = False
    reset: str = ''
    n_pairs: int = 0
    initiated: int = 0
    confirmed: int = 0
    terminated: int = 0
    merged: int = 0
    capped: int = 0
    not_initiated: int = 0
    pair_capped: int = 0
    left_coverage: int = 0
    dropped_numerical: int = 0
    n_tracks: int = 0
    n_confirmed: int = 0
    association: str = 'ipda'
    clusters: int = 0                 # association.method jipda: clusters of >= 2 tracks sharing detections,
    largest_cluster: int = 0          # the tracks in the largest,
    approximated_clusters: int = 0    # and the clusters above association.max_cluster (approximated)

    def summary(self) -> dict[str, str]:
        """The scan's counts by name, as text (a node's diagnostics); cluster counts with JIPDA only."""
        names = ['n_tracks', 'n_confirmed', 'n_pairs', 'initiated', 'terminated', 'merged', 'not_initiated',
                 'pair_capped', 'left_coverage']
        if self.association == 'jipda':
            names += ['clusters', 'largest_cluster', 'approximated_clusters']
        label = {'n_tracks': 'tracks', 'n_confirmed': 'confirmed', 'n_pairs': 'validated_pairs'}
        return {label.get(n, n): str(getattr(self, n)) for n in names}


class ImmIpdaTracker:
    """Multi-target IMM-IPDA tracker in the world frame.

    Parameters
    ----------
    config : the settings (:class:`~sonar_tracking.core.tracking.config.TrackerConfig`).
    modes : optional explicit modes, replacing those ``config.imm`` describes (their names must
        be among ``cv``, ``ccw``, ``cw``; probabilities of modes with the same name are added in
        the output). All modes must share one state dimension.
    """

    def __init__(self, config: TrackerConfig | None = None, modes: tuple[Mode, ...] | None = None) -> None:
        self._next_id = 1
        self._wrapped = False
        self.report = StepReport()
        self.configure(config or TrackerConfig(), modes)

    # ---------------------------------------------------------------- configuration
    def configure(self, config: TrackerConfig, modes: tuple[Mode, ...] | None = None) -> bool:
        """Apply new settings. Tracks are kept when the modes keep their number, else reset.

        Returns True when the tracks were reset.
        """
        modes = tuple(modes) if modes is not None else modes_from_config(config)
        if not modes:
            raise TrackingInputError('the tracker needs at least one mode')
        dims = {m.model.state_dim for m in modes}
        if len(dims) != 1:
            raise TrackingInputError(f'all modes must share one state dimension, got {sorted(dims)}')
        unknown = [m.name for m in modes if m.name not in MODE_NAMES]
        if unknown:
            raise TrackingInputError(f'mode names {unknown} are not among {list(MODE_NAMES)}')
        old_m = len(getattr(self, 'modes', ()))
        self.config = config
        self.modes = modes
        self.n = dims.pop()
        self.d = self.n // 2
        self.pi = mode_transition_matrix(len(modes), config.imm.mode_stay_probability)
        self.gamma = gate_threshold(config.detection.gate_probability, self.d)
        self._fq_cache: tuple | None = None
        self._default_R = config.detection.sigma ** 2 * np.eye(self.d)
        self._mode_field = [MODE_NAMES.index(m.name) for m in modes]
        reset = old_m != len(modes)
        if reset or not hasattr(self, '_x'):
            self.reset()
        return reset

    def reset(self) -> None:
        """Remove every track and forget the time; track ids keep counting."""
        m, n = len(self.modes), self.n
        # Component-major, tracks last (see the package docstring).
        self._ids = np.zeros(0, dtype=np.int64)
        self._x = np.zeros((n, m, 0))
        self._P = np.zeros((n, n, m, 0))
        self._mu = np.zeros((m, 0))
        self._exist = np.zeros(0)
        self._confirmed = np.zeros(0, dtype=bool)
        self._xc = np.zeros((n, 0))
        self._Pc = np.zeros((n, n, 0))
        # Time a track's estimate left the coverage, NaN inside; None while no scan had a coverage
        # (every track inside as far as anyone knows: all NaN).
        self._outside_since: np.ndarray | None = None
        # Where each tentative track's existence passed T_c, NaN before and after it fell below
        # existence.confirm_lapse (existence.confirm_distance).
        self._origin = np.zeros((2, 0))
        self._t: float | None = None
        self._output = np.zeros(0, TRACK_DTYPE)

    def initial_covariance(self, R: np.ndarray | None = None) -> np.ndarray:
        """``P_{0|0}`` of a track started from a measurement with covariance ``R`` (eqs. 47-48)."""
        return initial_covariance(self._default_R if R is None else R, self.config.init.speed_max)

    @property
    def time(self) -> float | None:
        """Stamp of the last processed scan, None before the first (or after a reset)."""
        return self._t

    @property
    def n_tracks(self) -> int:
        return len(self._ids)

    def tracks(self) -> np.ndarray:
        """The current tracks as a ``TRACK_DTYPE`` array (a copy of the last output)."""
        return self._output.copy()

    def mode_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of the per-mode estimates, tracks first: ``x (T, M, n)``, ``P (T, M, n, n)``, ``mu (T, M)``."""
        return (np.moveaxis(self._x, -1, 0).swapaxes(1, 2).copy(),
                np.moveaxis(self._P, (2, 3), (1, 0)).copy(), self._mu.T.copy())

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of the combined estimates (eqs. 41-42), tracks first: ``x (T, n)``, ``P (T, n, n)``."""
        return self._xc.T.copy(), np.moveaxis(self._Pc, -1, 0).copy()

    # ---------------------------------------------------------------- one scan
    def step(self, t: float, z, R=None, rho=None, coverage: Coverage | None = None) -> np.ndarray:
        """Process one scan and return all tracks (tentative and confirmed) as ``TRACK_DTYPE``.

        The returned array is read-only (it is not copied); copy it to change it.

        Parameters
        ----------
        t : scan time [s].
        z : ``(N, 2)`` world-frame positions of the detections.
        R : ``(N, 2, 2)`` their covariances; None uses ``detection.sigma^2 I``.
        rho : ``(N,)`` clutter density at each detection (SCMDE) [1/m^2], used when
            ``clutter.source`` is ``detection``; None, or source ``constant``, uses
            ``clutter.density``.
        coverage : the world-frame window this scan covered; None = unknown (no track ends for
            leaving coverage on this scan).
        """
        cfg = self.config
        t = float(t)
        if not math.isfinite(t):
            raise TrackingInputError(f'scan time {t} is not finite')
        check_forward('scan', t, self._t)
        if cfg.clutter.source == 'constant':
            rho = None
        z, R, rho = as_measurements(z, R, rho, default_R=self._default_R, default_rho=cfg.clutter.density)
        rep = self.report = StepReport(t=t, n_measurements=len(z), association=cfg.association.method)
        if self._t is not None:
            dt = t - self._t
            if dt == 0.0:
                rep.duplicate_stamp = True
                self._fill_counts(rep)
                return self._output
            if dt > cfg.track.max_gap:
                rep.reset = f'{dt:.6g} s since the previous scan exceeds track.max_gap = {cfg.track.max_gap:g} s'
                self.reset()
        keep, rep.rejected = check_measurements(z, R, rho)
        if rep.rejected:
            z, R, rho = z[keep], R[keep], rho[keep]

        pair_track = pair_meas = np.zeros(0, dtype=np.intp)
        if len(self._ids):
            # Overflow on absurd input shows as non-finite estimates, which _manage removes.
            with np.errstate(over='ignore', invalid='ignore', divide='ignore', under='ignore'):
                dt = t - cast(float, self._t)   # tracks exist only after a first scan
                pair_track, pair_meas = self._predict_update(dt, z, R, rho, rep)
            rep.n_pairs = len(pair_track)
            with np.errstate(over='ignore', invalid='ignore'):
                self._manage(rep, t, coverage)
            alive = self._alive
            # Pairs of surviving tracks (the tracks are removed below, with the new ones added).
            sel = alive[pair_track]
            pair_track, pair_meas = pair_track[sel], pair_meas[sel]
        else:
            alive = np.zeros(0, dtype=bool)
        exclude = self._confirmed if cfg.init.exclude == 'confirmed' else None
        unused = unused_measurements(len(z), pair_track, pair_meas, exclude)
        born = birth_measurements(unused, pair_meas, rho, cfg.init.max_per_scan)
        self._renew(alive, z[born], R[born])
        rep.initiated = len(born)
        rep.not_initiated = int(np.count_nonzero(unused)) - len(born)
        if len(self._ids) > cfg.track.max_tracks:
            cap = excess_tracks(self._exist, self._confirmed, cfg.track.max_tracks)
            rep.capped = int(np.count_nonzero(cap))
            self._keep(~cap)
        self._t = t
        self._output = self._records()
        self._fill_counts(rep)
        return self._output

    # ---------------------------------------------------------------- internals
    def _transitions(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        if self._fq_cache is None or self._fq_cache[0] != dt:
            F = np.stack([m.model.transition(dt) for m in self.modes])
            Q = np.stack([white_noise_acceleration(dt, m.noise, self.d) for m in self.modes])
            self._fq_cache = (dt, F, Q)
        return self._fq_cache[1:]

    def _predict_update(self, dt: float, z: np.ndarray, R: np.ndarray, rho: np.ndarray, rep: StepReport
                        ) -> tuple[np.ndarray, np.ndarray]:
        cfg, d = self.config, self.d
        meas_side = np.concatenate((z.T, R.reshape(len(z), d * d).T))                # (d + d^2, N)
        F, Q = self._transitions(dt)
        mu_pred, x0, P0 = interaction(self._mu, self._x, self._P, self.pi)           # eqs. (17)-(20)
        x_pred, P_pred = predict(x0, P0, F, Q)                                        # eqs. (22)-(23)
        e_pred = predict_existence(self._exist, cfg.existence.survival, cfg.existence.birth)  # eq. (24)

        # One contiguous gather per side: [H x, H P H^T] per track and [z, R] per measurement.
        track_side = np.concatenate((x_pred[:d], P_pred[:d, :d].reshape(d * d, *x_pred.shape[1:])))
        # Diagonals of R and of H P H^T (rows d, 2d + 1, ... of track_side) as strided views.
        r_max = np.maximum.reduce(R.reshape(len(z), d * d)[:, ::d + 1], axis=0) if len(z) else np.zeros(d)
        lo, hi = gate_boxes(track_side[:d], track_side[d::d + 1], r_max, self.gamma)
        n_tracks = len(self._ids)
        bounds = [0, n_tracks]
        search = BoxSearch(lo, hi, z)
        if n_tracks * len(z) > _CHUNK_PAIRS:
            counts = search.counts()
            drop = pair_budget(counts, self._confirmed, cfg.track.max_pairs)
            if drop.any():
                rep.pair_capped = int(np.count_nonzero(drop))
                keep = ~drop
                self._keep(keep)
                x_pred, P_pred, mu_pred, e_pred = x_pred[..., keep], P_pred[..., keep], mu_pred[:, keep], e_pred[keep]
                track_side, lo, hi, counts = track_side[..., keep], lo[keep], hi[keep], counts[keep]
                n_tracks = len(self._ids)
                search = BoxSearch(lo, hi, z)
            bounds = _chunk_bounds(counts, _CHUNK_PAIRS)
        # existence.decorrelation_time: the share of a full scan's evidence this scan carries.
        tau = cfg.existence.decorrelation_time
        weight = min(1.0, dt / tau) if tau > 0 else 1.0
        r = gated = None
        if cfg.association.method == 'jipda':
            r, gated = self._association(mu_pred, e_pred, track_side, search, z, meas_side, rho, bounds, lo, hi, rep)
        if len(bounds) == 2:   # one group: the search that counted the pairs finds them
            res, pt, pm = self._update_chunk(x_pred, P_pred, mu_pred, e_pred, track_side, search, z, meas_side, rho, r,
                                             gated, weight)
            self._x, self._P, self._mu, self._exist = res.x, res.P, res.mu, res.existence
        else:
            self._x, self._P = np.empty_like(x_pred), np.empty_like(P_pred)
            self._mu, self._exist = np.empty_like(mu_pred), np.empty_like(e_pred)
            pts, pms = [], []
            done = 0
            for a, b in zip(bounds[:-1], bounds[1:]):
                r_chunk = None if r is None else r[done:]
                # Contiguous copies: the kernels then see the arrays of the one-chunk path (no second compilation).
                xp, Pp, mp, ep, ts = (np.ascontiguousarray(v[..., a:b])
                                      for v in (x_pred, P_pred, mu_pred, e_pred, track_side))
                res, pt, pm = self._update_chunk(xp, Pp, mp, ep, ts, BoxSearch(lo[a:b], hi[a:b], z), z, meas_side, rho,
                                                 r_chunk, weight=weight)
                done += len(pt)
                self._x[..., a:b], self._P[..., a:b], self._mu[:, a:b] = res.x, res.P, res.mu
                self._exist[a:b] = res.existence
                pts.append(pt + a)
                pms.append(pm)
            pt, pm = np.concatenate(pts), np.concatenate(pms)
        self._xc, self._Pc = combine(self._mu, self._x, self._P)                     # eqs. (41)-(42)
        return pt, pm

    def _gate_chunk(self, track_side, search, meas_side):
        """Validated pairs of a contiguous group of tracks (eqs. 25-26): ``pt, pm, innov, in_gate``."""
        pt, pm = search.pairs()
        return gate_pairs(track_side, meas_side, pt, pm, self.gamma)                  # eqs. (25)-(26)

    def _update_chunk(self, x_pred, P_pred, mu_pred, e_pred, track_side, search, z, meas_side, rho, r=None,
                      gated=None, weight=1.0):
        """Gate and update a contiguous group of tracks (eqs. 25-40); pairs indexed within the group.

        ``r``: JIPDA factors of the group's pairs (the first ones are used), dividing their clutter
        density; ``gated``: the group's validated pairs when already gated; ``weight`` < 1: the
        existence update (eq. 40) takes the likelihood ratio of eq. (33) to this power
        (``existence.decorrelation_time``)."""
        cfg = self.config
        pt, pm, innov, in_gate = gated if gated is not None else self._gate_chunk(track_side, search, meas_side)
        rho_pairs = rho[pm] if r is None else rho[pm] / r[:len(pm)]
        res = ipda_update(x_pred, P_pred, mu_pred, e_pred, pt, innov, in_gate, rho_pairs,
                          cfg.detection.probability, cfg.detection.gate_probability)  # eqs. (28)-(40)
        if weight < 1.0:
            res = replace(res, existence=update_existence(e_pred, np.power(res.lam, weight)))
        return res, pt, pm

    def _association(self, mu_pred, e_pred, track_side, search, z, meas_side, rho, bounds, lo, hi, rep):
        """JIPDA factors ``r`` of every validated pair of the scan, in the order the chunks visit them,
        and the gated pairs when there is one chunk.

        The pairs of all chunks are gated first, so a cluster spanning chunks is treated whole; with
        several chunks each gates again for its update (the same pairs in the same order), so only
        one scalar per pair is kept across chunks."""
        cfg = self.config
        pdpg = cfg.detection.probability * cfg.detection.gate_probability
        tracks, meas, weight = [], [], []
        gated = None
        for a, b in zip(bounds[:-1], bounds[1:]):
            chunk_search = search if len(bounds) == 2 else BoxSearch(lo[a:b], hi[a:b], z)
            ts = track_side if len(bounds) == 2 else np.ascontiguousarray(track_side[..., a:b])
            pt, pm, innov, in_gate = gated = self._gate_chunk(ts, chunk_search, meas_side)
            like = pair_likelihoods(mu_pred[:, a:b], pt, innov, in_gate, rho[pm], cfg.detection.probability,
                                    cfg.detection.gate_probability)
            tracks.append(pt + a)
            meas.append(pm)
            weight.append(e_pred[pt + a] * like)
        factors = association_factors(np.concatenate(tracks), np.concatenate(meas), np.concatenate(weight),
                                      1.0 - e_pred * pdpg, cfg.association.max_cluster)
        rep.clusters, rep.largest_cluster, rep.approximated_clusters = (factors.clusters, factors.largest,
                                                                       factors.approximated)
        return factors.r, (gated if len(bounds) == 2 else None)

    def _keep(self, keep: np.ndarray) -> None:
        """Keep only the tracks ``keep`` (bool mask) in every per-track array."""
        self._ids, self._exist, self._confirmed = self._ids[keep], self._exist[keep], self._confirmed[keep]
        self._x, self._P, self._mu = self._x[..., keep], self._P[..., keep], self._mu[:, keep]
        self._xc, self._Pc = self._xc[:, keep], self._Pc[..., keep]
        if self._outside_since is not None:
            self._outside_since = self._outside_since[keep]
        self._origin = self._origin[:, keep]

    def _manage(self, rep: StepReport, t: float, coverage: Coverage | None) -> None:
        cfg = self.config.existence
        xc, Pc = self._xc, self._Pc
        alive = np.empty(len(self._ids), dtype=bool)
        before = self._confirmed.copy() if cfg.confirm_distance > 0 else None
        rep.dropped_numerical, rep.confirmed, rep.terminated = assess_tracks(
            xc, Pc, self._exist, self._confirmed, cfg.confirm, cfg.terminate,
            self.config.track.max_position_std ** 2, alive)
        if before is not None:
            # A tentative track whose existence fell below the lapse has lost what it followed; if it
            # picks up another echo, its distance counts from there (not a jump between two still echoes).
            self._origin[:, ~self._confirmed & (self._exist < cfg.confirm_lapse)] = np.nan
        if before is not None and rep.confirmed:
            # Confirmed only once moved from where its existence first passed T_c (a settled
            # estimate, unlike the first detection): until then it waits, tentative.
            newly = self._confirmed & ~before
            fresh = newly & np.isnan(self._origin[0])
            self._origin[:, fresh] = xc[:2, fresh]
            with np.errstate(invalid='ignore'):
                moved = np.hypot(xc[0] - self._origin[0], xc[1] - self._origin[1]) >= cfg.confirm_distance
            wait = newly & ~moved
            self._confirmed &= ~wait
            rep.confirmed -= int(np.count_nonzero(wait))
        if coverage is not None:
            inside = coverage.contains(xc[:2])
            before = self._outside_since if self._outside_since is not None else _filled(len(inside), np.nan)
            since = np.where(inside, np.nan, np.where(np.isnan(before), t, before))
            self._outside_since = since
            gone = alive & (t - since >= self.config.track.outside_time)    # NaN (inside) compares False
            alive &= ~gone
            rep.left_coverage = int(np.count_nonzero(gone))
        n_conf = int(np.count_nonzero(self._confirmed & alive))
        if self.config.track.merge_threshold > 0 and (rep.confirmed or n_conf > 1):
            # Duplicates are born while a target's first track is tentative (its measurements are
            # not yet kept from starting tracks), so they are found when a track is confirmed;
            # between confirmed tracks (targets coalescing) the check runs every scan.
            idx = (alive if rep.confirmed else alive & self._confirmed).nonzero()[0]
            dup = duplicate_tracks(xc[:, idx], Pc[..., idx], self._exist[idx], self._confirmed[idx],
                                   self._ids[idx], self.config.track.merge_threshold, self.config.track.max_pairs)
            rep.merged = int(np.count_nonzero(dup))
            if rep.merged:
                alive[idx[dup]] = False
        self._alive = alive

    def _renew(self, keep: np.ndarray, z: np.ndarray, R: np.ndarray) -> None:
        """Keep the tracks ``keep`` (bool mask) and start one tentative track per row of ``z``, ``R``
        (one-point initiation, eqs. 47-48): every per-track array rebuilt once."""
        k, kept = len(z), int(np.count_nonzero(keep))
        if k == 0 and kept == len(keep):
            return
        self._ids = self._ids[keep]
        self._ids = np.concatenate((self._ids, self._new_ids(k)))
        if self._outside_since is not None:
            self._outside_since = np.concatenate((self._outside_since[keep], _filled(k, np.nan)))
        self._origin = np.concatenate((self._origin[:, keep], _filled((2, k), np.nan)), axis=1)
        n, m, total = self.n, len(self.modes), kept + k
        x, P, mu = np.empty((n, m, total)), np.empty((n, n, m, total)), np.empty((m, total))
        exist, confirmed = np.empty(total), np.empty(total, dtype=bool)
        xc, Pc = np.empty((n, total)), np.empty((n, n, total))
        renew_tracks(keep, self._x, self._P, self._mu, self._exist, self._confirmed, self._xc, self._Pc,
                     np.ascontiguousarray(z, dtype=float), np.ascontiguousarray(R, dtype=float),
                     self.config.init.speed_max ** 2 / 3.0, float(self.config.existence.initial),
                     x, P, mu, exist, confirmed, xc, Pc)
        self._x, self._P, self._mu, self._exist, self._confirmed = x, P, mu, exist, confirmed
        self._xc, self._Pc = xc, Pc

    def _new_ids(self, k: int) -> np.ndarray:
        if self._next_id + k <= _ID_SPACE and not self._wrapped:
            ids = np.arange(self._next_id, self._next_id + k, dtype=np.int64)
            self._next_id += k
            return ids
        # Wrapped around the uint32 space: skip ids still in use.
        self._wrapped = True
        out: list[int] = []
        live = set(self._ids.tolist())
        while len(out) < k:
            if self._next_id >= _ID_SPACE:
                self._next_id = 1
            if self._next_id not in live:
                out.append(self._next_id)
            self._next_id += 1
        return np.asarray(out, dtype=np.int64)

    def _records(self) -> np.ndarray:
        out = np.zeros(len(self._ids), TRACK_DTYPE)
        if not len(out):
            out.flags.writeable = False
            return out
        xc, Pc = self._xc, self._Pc
        out['track_id'] = self._ids
        out['confirmed'] = self._confirmed
        if self._mode_field == [0, 1, 2] and self.n == 4:
            # The float fields in two runs (x .. existence, mode_cv .. cov_vyvy) as (T, k) views.
            state, modes_cov = out.view(_STATE_VIEW)['v'], out.view(_MODES_COV_VIEW)['v']
            state[:, :4] = xc.T
            state[:, 4] = self._exist
            modes_cov[:, :3] = self._mu.T
            modes_cov[:, 3:] = Pc.reshape(16, -1)[_COV_ENTRIES].T
        else:
            out['x'], out['y'], out['vx'], out['vy'] = xc
            out['existence'] = self._exist
            for j, f in enumerate(self._mode_field):
                out[('mode_cv', 'mode_ccw', 'mode_cw')[f]] += self._mu[j]
            out['cov_xx'], out['cov_xy'], out['cov_yy'] = Pc[0, 0], Pc[0, 1], Pc[1, 1]
            out['cov_vxvx'], out['cov_vyvy'] = Pc[2, 2], Pc[3, 3]
        out.flags.writeable = False         # handed out without a copy; the tracker keeps it as is
        return out

    def _fill_counts(self, rep: StepReport) -> None:
        rep.n_tracks = len(self._ids)
        rep.n_confirmed = int(np.count_nonzero(self._confirmed))


def _filled(shape, value: float) -> np.ndarray:
    """``np.full(shape, value)`` without its Python-level overhead."""
    out = np.empty(shape)
    out.fill(value)
    return out


def _run_view(first: str, count: int) -> np.dtype:
    """A dtype viewing ``count`` consecutive float64 fields of ``TRACK_DTYPE`` from ``first`` as one
    ``(count,)`` field ``v`` (checked against the record layout)."""
    names = TRACK_DTYPE.names or ()
    fields: Mapping[str, tuple] = TRACK_DTYPE.fields or {}
    start = names.index(first)
    offset = fields[first][1]
    for k, name in enumerate(names[start:start + count]):
        if fields[name] != (np.dtype('<f8'), offset + 8 * k):
            raise AssertionError(f'TRACK_DTYPE fields from {first} are not {count} consecutive float64')
    return np.dtype({'names': ['v'], 'formats': [('<f8', (count,))], 'offsets': [offset],
                     'itemsize': TRACK_DTYPE.itemsize})


# Record fields x, y, vx, vy, existence and mode_cv, mode_ccw, mode_cw, cov_xx, cov_xy, cov_yy,
# cov_vxvx, cov_vyvy, and the entries of the flattened 4 x 4 covariance the latter five take.
_STATE_VIEW = _run_view('x', 5)
_MODES_COV_VIEW = _run_view('mode_cv', 8)
_COV_ENTRIES = np.array([0, 1, 5, 10, 15])


def _chunk_bounds(counts: np.ndarray, limit: int) -> list[int]:
    """Boundaries splitting tracks ``0..T`` into contiguous groups whose ``counts`` sum to at most
    ``limit`` (a single track above the limit forms its own group)."""
    if not len(counts):
        return [0, 0]
    bounds = [0]
    csum = np.cumsum(counts)
    while bounds[-1] < len(counts):
        a = bounds[-1]
        base = csum[a - 1] if a else 0
        bounds.append(max(int(np.searchsorted(csum, base + limit, side='right')), a + 1))
    return bounds

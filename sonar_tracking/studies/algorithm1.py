"""Algorithm 1 of the ESC paper (§4): the desired clutter density for an SNR.

For ``P_D = 0.99, 0.98, ...`` (step ``pd_step``): ``P_fa = P_D^(1 + SNR)`` (line 3) and
``rho = P_fa / V_rc`` with ``V_rc = (2 sqrt(3) sigma_x)(2 sqrt(3) sigma_y)`` (lines 4-5); values of
rho outside ``(rho_min, rho_max)`` are skipped (line 6). Each remaining (P_D, rho) is a Monte
Carlo study of the IMM-IPDA (line 9) on measurement-level data: Scenario 1's target, detected with
probability P_D, its converted measurement drawn from the harbour sonar's noise (sigma_r, sigma_theta),
and Poisson clutter of density rho spread uniformly over the surveillance window; the tracker
knows P_D and rho. The confirmation threshold ``T_c`` is then swept (lines 7-14): nCTT(P_D, rho)
is the number of (run, scan) pairs with a confirmed true track at the smallest T_c whose rate of
confirmed false tracks is at most ``cft_target`` (0.005: "approximately 0.005"); rho_D is the rho
of the P_D with the largest nCTT (line 16). nCTT is a noisy count (the T_c that meets a rate of
0.005 rests on a few dozen false-track scans), so the argmax is taken on nCTT smoothed by a running
mean over five neighbouring candidates (fewer at the ends); the raw argmax is reported too. (With
our tracker nCTT rises as rho falls from rho_max and then levels off, a shape a fitted parabola
would misplace.)

The sweep over T_c is done after the runs, from each track's existence history
(:class:`~.confirmation.ConfirmationSweep`): one run per (P_D, rho) serves every T_c. The rate of
CFT here counts confirmed false tracks per scan; Table 1's "CFT scan" rate
(:func:`~.metrics.cft_scan_rate`) counts a scan with several once and is never larger.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sonar_tracking.core.detection import convert_measurements
from sonar_tracking.core.detection.scmde import PolarWindow
from sonar_tracking.core.tracking.config import PAPER_INITIATION, TrackerConfig
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker
from sonar_tracking.sim.amplitude import snr_linear
from sonar_tracking.sim.motion import ScriptedTrajectory
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY
from sonar_tracking.studies.confirmation import T_GRID, ConfirmationSweep
from sonar_tracking.studies.esc_study import resolution_cell_area
from sonar_tracking.studies.metrics import classify_tracks

__all__ = ['Algorithm1Config', 'candidates', 'run_candidate', 'choose', 'T_GRID']

@dataclass(frozen=True)
class Algorithm1Config:
    """Settings of one desired-density study."""

    snr_db: float = 8.0
    models: str = 'cv,ccw,cw'
    scans: int = 50
    pd_step: float = 0.01
    pd_min: float = 0.05
    rho_min: float = 1e-6
    rho_max: float = 5e-4
    cft_target: float = 0.005
    sigma_r: float = 5.0
    sigma_theta_deg: float = 0.1
    window: tuple = (1800.0, 3300.0, math.radians(-2.0), math.radians(22.0))
    tracker: dict = field(default_factory=dict)   # further TrackerConfig settings

    @property
    def v_rc(self) -> float:
        """V_rc with sigma_x = sigma_r and sigma_y = sigma_theta at 2500 m, the targets' range."""
        return resolution_cell_area(self.sigma_r, 2500.0 * math.radians(self.sigma_theta_deg))


def candidates(cfg: Algorithm1Config) -> list[tuple[float, float]]:
    """``[(P_D, rho), ...]`` of lines 2-6."""
    snr = snr_linear(cfg.snr_db)
    out = []
    pd = 0.99
    while pd >= cfg.pd_min - 1e-12:
        rho = pd ** (1.0 + snr) / cfg.v_rc
        if cfg.rho_min < rho < cfg.rho_max:
            out.append((round(pd, 6), rho))
        pd -= cfg.pd_step
    return out


def run_candidate(item: tuple[Algorithm1Config, float, float], seed: np.random.SeedSequence) -> dict:
    """One Monte Carlo run at (P_D, rho): per scan and T in T_GRID, CTT present and CFT count."""
    cfg, pd, rho = item
    rng = np.random.default_rng(seed)
    window = PolarWindow(*cfg.window)
    flat = {'imm.models': cfg.models, 'detection.probability': pd, 'clutter.source': 'constant',
            'clutter.density': rho, 'existence.confirm': float(T_GRID[0])}
    flat.update(PAPER_INITIATION)   # the paper's one-point initiation (core.tracking.config)
    flat.update(cfg.tracker)
    trk = ImmIpdaTracker(TrackerConfig.from_flat(flat))
    target = ScriptedTrajectory(50.0, 200.0, 12.0 / math.sqrt(2.0), 12.0 / math.sqrt(2.0))
    sx, sy = HARBOUR_SONAR_XY
    sig_b = math.radians(cfg.sigma_theta_deg)
    sweep = ConfirmationSweep()
    has_ctt = np.zeros((cfg.scans, len(T_GRID)), bool)
    n_false = np.zeros((cfg.scans, len(T_GRID)), np.int32)
    P0 = None
    for k in range(cfg.scans):
        t = float(k + 1)
        truth = target.state(t)
        r_t = math.hypot(truth[0] - sx, truth[1] - sy)
        b_t = math.atan2(truth[1] - sy, truth[0] - sx)
        n_c = rng.poisson(rho * window.area)
        r = np.sqrt(rng.uniform(window.r_min ** 2, window.r_max ** 2, n_c))
        b = rng.uniform(window.b_min, window.b_max, n_c)
        if rng.random() < pd:
            r = np.append(r, r_t + cfg.sigma_r * rng.standard_normal())
            b = np.append(b, b_t + sig_b * rng.standard_normal())
        z, R = convert_measurements(r, b, cfg.sigma_r, sig_b, (sx, sy, 0.0))
        if P0 is None:
            _, R0 = convert_measurements(np.array([r_t]), np.array([b_t]), cfg.sigma_r, sig_b, (sx, sy, 0.0))
            P0 = trk.initial_covariance(R0[0])
        tracks = trk.step(t, z, R)
        if not len(tracks):
            continue
        est = np.column_stack([tracks[f] for f in ('x', 'y', 'vx', 'vy')])
        label = classify_tracks(truth[None, :], est, P0).label
        has_ctt[k], n_false[k] = sweep.update(tracks['track_id'].tolist(), tracks['existence'].tolist(), label)
    return {'has_ctt': has_ctt, 'n_false': n_false}


def choose(cfg: Algorithm1Config, results: dict[tuple[float, float], list[dict]]) -> dict:
    """Lines 11-16: per candidate the T_c and nCTT, and rho_D = the rho of the largest nCTT."""
    rows = []
    for (pd, rho), runs in results.items():
        has = np.array([r['has_ctt'] for r in runs])        # (runs, scans, T)
        nf = np.array([r['n_false'] for r in runs])
        cft = nf.mean(axis=(0, 1))                            # (T,)
        ok = np.flatnonzero(cft <= cfg.cft_target)
        if len(ok) == 0:
            rows.append({'pd': pd, 'rho': rho, 't_c': None, 'n_ctt': 0, 'cft_rate': float(cft[-1])})
            continue
        j = ok[0]
        rows.append({'pd': pd, 'rho': rho, 't_c': float(T_GRID[j]), 'n_ctt': int(has[:, :, j].sum()),
                     'cft_rate': float(cft[j])})
    rows.sort(key=lambda row: row['rho'])
    raw = max(rows, key=lambda row: row['n_ctt'])
    counts = np.array([row['n_ctt'] for row in rows], dtype=float)
    smooth = np.array([counts[max(0, i - 2):i + 3].mean() for i in range(len(counts))])
    for row, v in zip(rows, smooth):
        row['n_ctt_smoothed'] = float(v)
    best = rows[int(np.argmax(smooth))]
    return {'desired_clutter_density': best['rho'], 'pd': best['pd'], 't_c': best['t_c'], 'n_ctt': best['n_ctt'],
            'method': 'running mean of 5', 'raw_argmax_density': raw['rho'], 'candidates': rows}

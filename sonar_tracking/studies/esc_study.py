"""The ESC paper's simulation study (§5): Scenario 1 and 2 from sectors to tracks, by method.

One Monte Carlo run simulates the scenario's sectors once and hands the *same* sectors to every
method (common random numbers: the methods differ only by their thresholds), each method with
its own detector (SCMDE, and ESC or a fixed threshold) and IMM-IPDA tracker (a single CV model,
i.e. IPDA, in Scenario 1; CV + CCW + CW in Scenario 2, as in §5). Per scan it records whether the
target has a confirmed true track (eqs. 47-48 against ``P_{0|0}``), the CTT's position error
(eq. 49), the threshold, the density the detector measured and the number of confirmed false
tracks.

The tracker needs a detection probability P_D (eqs. 32-33), which depends on the threshold and
on the unknown clutter law. A fixed threshold tau gets P_D = exp(-tau / (1 + SNR)), the value for
the Chi-squared clutter (lam = 1) that Algorithm 1 assumes. ESC aims at the density rho_D, where
P_fa = rho_D V_rc; the tracker then uses that operating point's P_D = (rho_D V_rc)^(1 / (1 + SNR))
(Algorithm 1, line 3), which holds for any lam once ESC has converged.

Scenario 2's ESC measures the density near the confirmed track with the highest existence (§5.2).

With ``sweep_tc`` the trackers confirm at the lowest T_c of :data:`~.confirmation.T_GRID` and each
run also records, per scan and per T_c of the grid, whether a true track is confirmed and how many
false ones are (:class:`~.confirmation.ConfirmationSweep`), so that T_c can be screened per method
after the runs (:mod:`.esc_table`). With ``confirm_by_method`` each method's tracker confirms at its
own T_c during the run (track starts and Scenario 2's density measurement follow it), and every
run records the T_c its tracker holds, read from the tracker's configuration (``confirm``). With
``gospa`` each run also records per scan the GOSPA between the target and the confirmed tracks.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sonar_tracking.core.detection import ActiveDetector, DetectorConfig, best_track_focus, convert_measurements
from sonar_tracking.core.tracking.config import PAPER_INITIATION, TrackerConfig
from sonar_tracking.core.tracking.tracker import ImmIpdaTracker
from sonar_tracking.sim import SimConfig, Simulator
from sonar_tracking.sim.amplitude import snr_linear
from sonar_tracking.sim.presets import HARBOUR_SONAR_XY
from sonar_tracking.studies.confirmation import T_GRID, ConfirmationSweep
from sonar_tracking.studies.evidence import GospaSpec
from sonar_tracking.studies.metrics import (
    classify_tracks,
    confirmed_false_track_rate,
    confirmed_true_track_rate,
    evaluate_scan,
    position_rmse,
)

__all__ = ['Method', 'parse_methods', 'StudyConfig', 'run_once', 'summarise', 'resolution_cell_area', 'design_pd',
           'fixed_pd', 'PAPER_DESIRED_DENSITY']

#: The paper's desired densities [1/m^2]: Scenario 1 (IPDA), Scenario 2 (IMM-IPDA), SNR 8 dB.
PAPER_DESIRED_DENSITY = {'scenario1': 2.21e-5, 'scenario2': 7.52e-5}


@dataclass(frozen=True)
class Method:
    """``esc`` (adaptive, from the study's tau_0), ``esc:T0`` (adaptive from T0) or ``fixed:T``."""

    name: str
    threshold: float | None = None   # the fixed threshold, or ESC's initial one (None: the study's)
    esc: bool = False


def parse_methods(text: str) -> tuple[Method, ...]:
    """``'esc,esc:5,fixed:2,fixed:4'`` -> methods; ValueError says what is wrong."""
    out = []
    for item in (s.strip() for s in text.split(',') if s.strip()):
        kind, _, value = item.partition(':')
        if kind not in ('esc', 'fixed') or (kind == 'fixed' and not value):
            raise ValueError(f'unknown method {item!r}: use esc, esc:T0 or fixed:T')
        tau = None
        if value:
            try:
                tau = float(value)
            except ValueError:
                raise ValueError(f'method {item!r}: the threshold after ":" must be a number') from None
            if not tau > 0:
                raise ValueError(f'method {item!r}: the threshold must be > 0')
        out.append(Method(item, tau, esc=kind == 'esc'))
    if not out:
        raise ValueError('no methods given')
    if len({m.name for m in out}) != len(out):
        raise ValueError(f'methods repeat in {text!r}')
    return tuple(out)


def resolution_cell_area(sigma_x: float, sigma_y: float) -> float:
    """``V_rc = (2 sqrt(3) sigma_x)(2 sqrt(3) sigma_y)`` (Algorithm 1, lines 4-5)."""
    return 12.0 * sigma_x * sigma_y


def design_pd(snr_db: float, rho_d: float, v_rc: float) -> float:
    """P_D where the clutter density is rho_D: ``(rho_D V_rc)^(1 / (1 + SNR))`` (Algorithm 1, line 3)."""
    return float(min(1.0, (rho_d * v_rc) ** (1.0 / (1.0 + snr_linear(snr_db)))))


def fixed_pd(tau: float, snr_db: float) -> float:
    """P_D of a fixed threshold for Chi-squared clutter (lam = 1): ``exp(-tau / (1 + SNR))``."""
    return float(math.exp(-tau / (1.0 + snr_linear(snr_db))))


@dataclass(frozen=True)
class StudyConfig:
    """One study: scenario, length, clutter, methods and the desired density."""

    scenario: str = 'scenario1'
    scans: int = 50
    lam: float = 1.2                      # Scenario 1's clutter rate (Scenario 2 has its own regions)
    tau0: float = 3.0                     # ESC's initial threshold
    desired_density: float = 2.21e-5
    snr_db: float = 8.0
    methods: tuple[Method, ...] = field(default_factory=lambda: parse_methods('esc,fixed:2,fixed:4,fixed:6'))
    sigma_r: float = 5.0
    sigma_theta_deg: float = 0.1
    confirm: float | None = None          # the tracker's T_c (None: the tracker's default)
    sweep_tc: bool = False                # record every T_c of T_GRID (the tracker confirms at its lowest)
    confirm_by_method: tuple[tuple[str, float], ...] = ()   # (method name, T_c) run inside the run
    gospa: GospaSpec | None = None        # also record GOSPA per scan with these settings

    def confirm_for(self, method: str) -> float | None:
        """The T_c ``method``'s tracker is built with (None: the tracker's default)."""
        own = dict(self.confirm_by_method)
        if method in own:
            return float(own[method])
        if self.sweep_tc:
            return float(T_GRID[0])
        return self.confirm

    @property
    def models(self) -> str:
        return 'cv' if self.scenario == 'scenario1' else 'cv,ccw,cw'

    @property
    def v_rc(self) -> float:
        """Resolution-cell area at the targets' range (about 2500 m from the sonar)."""
        return resolution_cell_area(self.sigma_r, 2500.0 * math.radians(self.sigma_theta_deg))


def _tracker(study: StudyConfig, method: str, pd: float) -> ImmIpdaTracker:
    flat = {'imm.models': study.models, 'detection.probability': pd, **PAPER_INITIATION}
    confirm = study.confirm_for(method)
    if confirm is not None:
        flat['existence.confirm'] = confirm
    return ImmIpdaTracker(TrackerConfig.from_flat(flat))


def run_once(study: StudyConfig, seed: np.random.SeedSequence) -> dict[str, dict[str, np.ndarray]]:
    """One Monte Carlo run of every method on the same simulated sectors."""
    rng = np.random.default_rng(seed)
    flat = {'duration': float(study.scans), 'snr_db': study.snr_db}
    if study.scenario == 'scenario1':
        flat['clutter_lambda'] = study.lam
    sim = Simulator(SimConfig.for_scenario(study.scenario, **flat), rng)
    sectors = [sim.next_sector() for _ in range(study.scans)]
    truths = [sim.truth(s.stamp)[1] for s in sectors]
    # P_{0|0} of eqs. 47-48: a track started from a measurement where the target starts.
    x0, y0 = truths[0][0, :2]
    r0 = math.hypot(x0 - HARBOUR_SONAR_XY[0], y0 - HARBOUR_SONAR_XY[1])
    b0 = math.atan2(y0 - HARBOUR_SONAR_XY[1], x0 - HARBOUR_SONAR_XY[0])
    _, R0 = convert_measurements(np.array([r0]), np.array([b0]), study.sigma_r, math.radians(study.sigma_theta_deg))
    out = {}
    for method in study.methods:
        tau0 = method.threshold if method.threshold is not None else study.tau0
        values = {'threshold.initial': tau0,
                  'esc.enabled': method.esc, 'cells.sigma_r': study.sigma_r,
                  'cells.sigma_theta_deg': study.sigma_theta_deg}
        if method.esc and study.scenario == 'scenario2':
            values['esc.density_source'] = 'best_track'
        det = ActiveDetector(DetectorConfig.from_flat(values), study.desired_density)
        pd = design_pd(study.snr_db, study.desired_density, study.v_rc) if method.esc else fixed_pd(method.threshold,
                                                                                                   study.snr_db)
        trk = _tracker(study, method.name, pd)
        P0 = trk.initial_covariance(R0[0])
        k_scans = study.scans
        rec = {'has_ctt': np.zeros(k_scans, bool), 'error': np.full(k_scans, np.nan), 'threshold': np.zeros(k_scans),
               'clutter_density': np.zeros(k_scans), 'n_false': np.zeros(k_scans, int)}
        if study.confirm_by_method:
            rec['confirm'] = float(trk.config.existence.confirm)
        if study.gospa is not None:
            rec['gospa'] = np.zeros(k_scans)
        if study.sweep_tc:
            sweep = ConfirmationSweep()
            rec['has_ctt_t'] = np.zeros((k_scans, len(T_GRID)), bool)
            rec['n_false_t'] = np.zeros((k_scans, len(T_GRID)), np.int32)
        focus = None
        for k, s in enumerate(sectors):
            r = det.process(s.amplitudes, s.geometry, s.pose, focus)
            d = r.detections
            z = np.column_stack([d['x'], d['y']])
            R = np.empty((len(d), 2, 2))
            R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = d['cov_xx'], d['cov_xy'], d['cov_xy'], d['cov_yy']
            tracks = trk.step(s.stamp, z, R, d['clutter_density'])
            ev = evaluate_scan(truths[k], tracks, P0)
            if study.sweep_tc and len(tracks):
                est = np.column_stack([tracks[f] for f in ('x', 'y', 'vx', 'vy')])
                label = classify_tracks(truths[k], est, P0).label
                rec['has_ctt_t'][k], rec['n_false_t'][k] = sweep.update(tracks['track_id'].tolist(),
                                                                        tracks['existence'].tolist(), label)
            if study.gospa is not None:
                conf = tracks[tracks['confirmed'] != 0]
                rec['gospa'][k] = study.gospa(truths[k][:, :2], np.column_stack([conf['x'], conf['y']])).distance
            rec['has_ctt'][k], rec['error'][k] = ev.has_ctt[0], ev.error[0]
            rec['threshold'][k], rec['clutter_density'][k], rec['n_false'][k] = r.threshold, r.mean_density, ev.n_false
            focus = best_track_focus(tracks)
        out[method.name] = rec
    return out


def summarise(study: StudyConfig, runs: list[dict]) -> dict:
    """Per method: CTTR and RMSE per scan, mean threshold and density per scan, CFT rate."""
    methods = {}
    for m in study.methods:
        has = np.array([r[m.name]['has_ctt'] for r in runs])
        err = np.array([r[m.name]['error'] for r in runs])
        methods[m.name] = {
            'cttr': confirmed_true_track_rate(has).tolist(),
            'rmse': [None if math.isnan(v) else v for v in position_rmse(err).tolist()],
            'threshold': np.mean([r[m.name]['threshold'] for r in runs], axis=0).tolist(),
            'clutter_density': np.mean([r[m.name]['clutter_density'] for r in runs], axis=0).tolist(),
            'cft_rate': confirmed_false_track_rate([r[m.name]['n_false'] for r in runs]),
        }
    return methods

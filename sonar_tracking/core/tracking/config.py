"""Settings of the IMM-IPDA tracker: one frozen :class:`~sonar_tracking.core.config.Config`.

The paper (ESC, §2.4 and §5) fixes the mode transition matrix (eq. 21, ``p_stay = 0.98``), the
modes (CV and CTR left and right) and the turn rate of Scenario 2 (Table 2, 3 deg/s). It does not
give the process noise, ``P_D``, the gate, the existence chain or the thresholds; the defaults
here are ours and say so in their descriptions. ``config/imm_ipda.yaml`` holds the values for
the paper's harbour scenarios.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

from sonar_tracking.core.config import Config, ConfigError, setting

__all__ = ['ImmConfig', 'DetectionConfig', 'ClutterConfig', 'ExistenceConfig', 'InitConfig', 'TrackConfig',
           'AssociationConfig', 'TrackerConfig', 'MODE_NAMES', 'PAPER_INITIATION']

#: The paper's one-point initiation (a track from every detection no confirmed track validated);
#: studies reproducing the ESC paper merge this into their settings (the default, ``all``, starts
#: none from a detection a tentative track validated: bounded in clutter, lower CTTR in dense clutter).
PAPER_INITIATION = {'init.exclude': 'confirmed'}
#: Mode names the tracker knows; ``TRACK_DTYPE`` has one probability field per name.
MODE_NAMES = ('cv', 'ccw', 'cw')
#: Mode sets ``imm.models`` accepts: any non-empty subset, in the order above.
_MODE_SETS = tuple(','.join(c) for k in (3, 1, 2) for c in itertools.combinations(MODE_NAMES, k))


@dataclass(frozen=True)
class ImmConfig(Config):
    """Motion modes (eqs. 3-4), their process noise and the mode transition matrix (eq. 21)."""

    models: str = setting('cv,ccw,cw', 'IMM modes: cv (eq. 3), ccw (eq. 4, +Omega), cw (eq. 4, -Omega); '
                          '"cv" alone is a single-model IPDA', choices=_MODE_SETS)
    turn_rate_ccw_deg: float = setting(3.0, 'turn rate of the ccw mode (Table 2: 3 deg/s)', unit='deg/s',
                                       low=0.0, high=180.0, low_open=True)
    turn_rate_cw_deg: float = setting(3.0, 'turn rate magnitude of the cw mode (Table 2: 3 deg/s)', unit='deg/s',
                                      low=0.0, high=180.0, low_open=True)
    mode_stay_probability: float = setting(0.98, 'diagonal of the mode transition matrix, eq. (21)',
                                           low=0.0, high=1.0, low_open=True)
    noise_cv: float = setting(0.01, 'acceleration noise PSD q of the cv mode (not in the paper)',
                              unit='m^2/s^3', low=0.0, high=1e6)
    noise_ctr: float = setting(0.01, 'acceleration noise PSD q of the ccw and cw modes (not in the paper)',
                               unit='m^2/s^3', low=0.0, high=1e6)

    @property
    def mode_names(self) -> tuple[str, ...]:
        """The modes in order, e.g. ``('cv', 'ccw', 'cw')``."""
        return tuple(m.strip() for m in self.models.split(','))

    def validate(self) -> None:
        if len(self.mode_names) > 1 and self.mode_stay_probability == 1.0:
            raise ConfigError('mode_stay_probability = 1 freezes the modes; use < 1 with several models')


@dataclass(frozen=True)
class DetectionConfig(Config):
    """Sensor detection model (eqs. 28, 32-33) and the validation gate (eq. 25)."""

    probability: float = setting(0.9, 'target detection probability P_D (eqs. 32-33)', low=0.0, high=1.0,
                                 low_open=True)
    gate_probability: float = setting(0.99, 'gate probability P_G; the gate size gamma_G of eq. (25) is its '
                                      'chi-square(2) quantile; 1 = no gate', low=0.5, high=1.0)
    sigma: float = setting(5.0, 'std of x and y of a detection that carries no covariance', unit='m',
                           low=0.0, high=1e6, low_open=True)


@dataclass(frozen=True)
class ClutterConfig(Config):
    """Clutter measurement density rho_{k,i} of eqs. (32)-(33)."""

    source: str = setting('detection', 'detection = each detection\'s clutter_density (SCMDE), '
                          'constant = clutter.density for all', choices=('detection', 'constant'))
    density: float = setting(7.52e-5, 'constant clutter density (Scenario 2 rho_D: 7.52e-5)', unit='1/m^2',
                             low=0.0, high=1e6, low_open=True)


@dataclass(frozen=True)
class ExistenceConfig(Config):
    """Target existence: Markov chain one (eq. 24), initial value and track management thresholds."""

    survival: float = setting(0.98, 'P(chi_k | chi_{k-1}) per scan, eq. (24)', low=0.0, high=1.0, low_open=True)
    birth: float = setting(0.0, 'P(chi_k | not chi_{k-1}) per scan, eq. (24)', low=0.0, high=1.0)
    initial: float = setting(0.02, 'existence probability of a new track (not in the paper)', low=0.0, high=1.0,
                             low_open=True, high_open=True)
    confirm: float = setting(0.98, 'T_c: a track is confirmed once its existence exceeds this (not in the paper)',
                             low=0.0,
                             high=1.0, low_open=True, high_open=True)
    terminate: float = setting(0.01, 'a track is terminated when its existence falls below this (not in the paper)',
                               low=0.0, high=1.0, high_open=True)
    confirm_distance: float = setting(0.0, 'a track is confirmed only once its estimate has also moved this far '
                                      'from where its existence first exceeded confirm (taken again after its '
                                      'existence fell below confirm_lapse): static echoes (frozen speckle, a rock) are '
                                      'never confirmed; 0 = off (not in the paper)', unit='m',
                                      low=0.0, high=1e6)
    confirm_lapse: float = setting(0.5, 'with confirm_distance: a tentative track whose existence falls below this '
                                   'has lost what it followed, and its distance is counted afresh from where its '
                                   'existence next exceeds confirm (not in the paper)', low=0.0, high=1.0,
                                   low_open=True, high_open=True)
    decorrelation_time: float = setting(0.0, 'scans closer together than this are not independent evidence: the '
                                        'existence update (eq. 40) takes the likelihood ratio of eq. (33) to the '
                                        'power dt / decorrelation_time (at most 1), so the frames of a second weigh as '
                                        '1 / decorrelation_time independent scans at any frame rate (frozen speckle, '
                                        'a target\'s fading); 0 = every scan independent, as the paper takes them (not '
                                        'in the paper)', unit='s', low=0.0, high=1e6)

    def validate(self) -> None:
        if not self.terminate < self.initial:
            raise ConfigError(f'terminate = {self.terminate} must be < initial = {self.initial}')
        if not self.terminate < self.confirm:
            raise ConfigError(f'terminate = {self.terminate} must be < confirm = {self.confirm}')
        if self.confirm_distance > 0 and not self.confirm_lapse < self.confirm:
            raise ConfigError(f'confirm_lapse = {self.confirm_lapse} must be < confirm = {self.confirm}')


@dataclass(frozen=True)
class InitConfig(Config):
    """One-point track initiation: position from the measurement, velocity from a prior; a budget per scan."""

    speed_max: float = setting(15.0, 'largest target speed; each velocity component of a new track has '
                               'mean 0 and variance speed_max^2 / 3', unit='m/s', low=0.0, high=1e4, low_open=True)
    exclude: str = setting('all', 'detections validated by these tracks start no track: confirmed = the paper\'s '
                           'one-point initiation (every detection no confirmed track validated), all = also '
                           'those in a tentative track\'s gate (tentative tracks grow with the area covered, not '
                           'with the clutter)', choices=('all', 'confirmed'))
    max_per_scan: int = setting(1000, 'most tracks started per scan; when more detections are unused, those no '
                                'track validated come first, then the lowest clutter density (see management); '
                                'the paper studies set it high enough never to bind', low=0, high=10_000_000)


@dataclass(frozen=True)
class TrackConfig(Config):
    """Track bookkeeping beyond the paper: duplicates, caps on tracks and pairs, coverage, long gaps."""

    merge_threshold: float = setting(9.49, 'a track whose state lies within this squared Mahalanobis distance '
                                     '(summed covariances, 4 dof) of an older confirmed track is removed as a '
                                     'duplicate; 0 = never', low=0.0, high=1e6)
    max_position_std: float = setting(30.0, 'a track whose position std (largest axis) exceeds this is terminated: '
                                      'it no longer follows anything', unit='m', low=0.0, high=1e9, low_open=True)
    max_tracks: int = setting(5000, 'most tracks kept after each scan (new ones included); beyond, the least '
                              'likely tentative tracks are dropped', low=1, high=10_000_000)
    max_pairs: int = setting(100_000, 'most track-detection candidate pairs per scan; beyond, the tentative '
                             'tracks with the most candidates (densest clutter) are dropped first, then '
                             'confirmed ones', low=1, high=1_000_000_000)
    outside_time: float = setting(10.0, 'a track whose estimate has been outside the sensor coverage passed to '
                                  'step() for this long ends', unit='s', low=0.0, high=1e9)
    max_gap: float = setting(60.0, 'a scan more than this after the previous one restarts the tracker',
                             unit='s', low=0.0, high=1e9, low_open=True)


@dataclass(frozen=True)
class AssociationConfig(Config):
    """How tracks share a scan's detections: independent IPDAs (the paper) or Joint IPDA (not in the paper)."""

    method: str = setting('ipda', 'ipda = every track an independent IMM-IPDA (the ESC paper); jipda = IMM-JIPDA '
                          '(Musicki & Evans 2004): tracks that share validated detections compete for them',
                          choices=('ipda', 'jipda'))
    max_cluster: int = setting(8, 'jipda: clusters of tracks sharing detections up to this many tracks are exact '
                               '(work ~ 2^max_cluster per shared detection); larger ones use the LM-IPDA '
                               'approximation (see core/tracking/jipda.py)', low=1, high=12)


@dataclass(frozen=True)
class TrackerConfig(Config):
    """Every setting of :class:`~sonar_tracking.core.tracking.tracker.ImmIpdaTracker`."""

    imm: ImmConfig = ImmConfig()
    detection: DetectionConfig = DetectionConfig()
    clutter: ClutterConfig = ClutterConfig()
    existence: ExistenceConfig = ExistenceConfig()
    init: InitConfig = InitConfig()
    track: TrackConfig = TrackConfig()
    association: AssociationConfig = AssociationConfig()

    def turn_rates(self) -> dict[str, float]:
        """Signed turn rate [rad/s] of each CTR mode: ccw positive, cw negative (REP-103)."""
        return {'ccw': math.radians(self.imm.turn_rate_ccw_deg), 'cw': -math.radians(self.imm.turn_rate_cw_deg)}

"""Settings of the GPF tracker: one frozen :class:`~sonar_tracking.core.config.Config`, grouped by role.

The FLS paper fixes the number of particles (K = 300 in the tank, 200 at sea, §5.1 and §5.2.1),
the feature set (Table 7: 20, 17, 3, 6, 24), the likelihood form (eq. 13), the fusion rules
(eqs. 14-18, Tables 8-9) and the initial spread of step 1 (§4.2.3). Everything else (process
noise, window size, thresholds ``T_i``, the lost and template rules) is ours and says so.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.fls import PAPER_FEATURES
from sonar_tracking.core.fls.windows import WINDOW_SHAPE_FEATURES
from sonar_tracking.core.gpf.cues import MAX_WINDOW

__all__ = ['MotionConfig', 'CueConfig', 'FusionConfig', 'BirthConfig', 'LostConfig', 'TemplateConfig',
           'GpfConfig', 'FUSION_MODES', 'FUSION_SWITCHES', 'PAPER_INITIAL_VARIANCE_PX', 'PAPER_PIXEL']

#: Fusion strategies: adaptive (eq. 18), multiplicative (eq. 15), weighted (eq. 14).
FUSION_MODES = ('af', 'mf', 'wf')
#: How adaptive fusion chooses: eq. (18) alone, or eq. (18) and WF while another track is inside
#: the particle cloud (:mod:`.fusion`).
FUSION_SWITCHES = ('cues', 'crossing')

#: §4.2.3 step 1: initial particles N(x; x_target, 45), N(y; y_target, 40), variances in the
#: paper's image pixels (x across the image, y along range).
PAPER_INITIAL_VARIANCE_PX = (45.0, 40.0)
#: The pixel size [m] at which we read those variances (our FLS image's default resolution).
PAPER_PIXEL = 0.1


@dataclass(frozen=True)
class MotionConfig(Config):
    """Constant-velocity motion (eq. 3 of the ESC paper, :mod:`~..tracking.motion`) with white-noise
    acceleration (:mod:`~..tracking.noise`); the FLS paper does not give its kinematics model.

    ``q`` sets how wide the prediction of eqs. (10)-(12) is, and with it how informative the update
    of eqs. (6)-(8) can be: the particles are drawn from the prediction, and every particle whose
    window is background keeps a weight of ``exp(-sum beta_i d_i^2 / 2)`` relative to one on the
    target (eq. 13; about e^-3 to e^-5 for MF), so the wider the prediction beyond the target's
    echo, the more the weighted mean of eq. (8) is pulled toward the middle of the cloud. The
    measurements behind ``q`` are in ``docs/experiments/2026-11-21-fls-gpf-study.md``."""

    noise: float = setting(0.001, 'acceleration noise PSD q of the constant-velocity model (ours: towed targets '
                           'wander about 0.2 m off their line in a 5 s frame; larger values widen the prediction '
                           'and weaken the update, see MotionConfig)', unit='m^2/s^3', low=0.0, high=1e3,
                           low_open=True)


@dataclass(frozen=True)
class CueConfig(Config):
    """The feature cues: which Table 2 features, where they are measured and the likelihood of eq. (13)."""

    features: tuple[float, ...] = setting(PAPER_FEATURES, 'Table 2 feature numbers used as cues (Table 7: 20, 17, '
                                          '3, 6, 24)', low=1, high=30)
    window: float = setting(0.7, 'side of the square window around a particle whose features it gets (ours; '
                            'rounded to an odd number of pixels, at least 3)', unit='m', low=0.0, high=20.0,
                            low_open=True)
    pixel: float = setting(0.1, 'window features are measured on the image block-averaged to the coarsest pixel '
                           'not larger than this (ours: the cue scales were calibrated on 0.1 m pixels, and the '
                           'work per particle grows with the window\'s area in pixels); 0 = the image\'s own '
                           'pixels', unit='m', low=0.0, high=20.0)
    alpha: float = setting(1.0, 'likelihood-function noise alpha of eq. (13); the distance control '
                           'coefficients beta_i are 1/sigma_i^2 of each feature (sonar_tracking.core.gpf.cues)',
                           low=0.0, high=100.0, low_open=True)

    @property
    def numbers(self) -> tuple[int, ...]:
        """The features as Table 2 integers."""
        return tuple(int(f) for f in self.features)

    def validate(self) -> None:
        if not self.features:
            raise ConfigError('cues.features is empty: give at least one Table 2 feature number (e.g. 3)')
        if any(f != int(f) for f in self.features):
            raise ConfigError(f'cues.features = {list(self.features)} must be whole Table 2 numbers 1..30')
        if len(set(self.numbers)) != len(self.numbers):
            raise ConfigError(f'cues.features = {list(self.numbers)} names a feature twice')
        # The cues' pixel is between pixel / 2 and pixel (a block of whole image pixels), so the window
        # has up to 2 window / pixel pixels; beyond MAX_WINDOW it would be cut.
        if self.pixel > 0.0 and 2.0 * self.window / self.pixel > MAX_WINDOW + 1:
            raise ConfigError(f'window {self.window:g} m spans up to {2.0 * self.window / self.pixel:.0f} pixels '
                              f'of cues.pixel {self.pixel:g} m (blocks of whole image pixels are between half of '
                              f'it and it); at most {MAX_WINDOW}: raise cues.pixel to at least '
                              f'{2.0 * self.window / (MAX_WINDOW + 1):.3g} m or shrink cues.window')
        fixed = sorted(set(self.numbers) & WINDOW_SHAPE_FEATURES)
        if fixed:
            raise ConfigError(f'cues.features {fixed} are the same for every window (area, perimeter and shape of '
                              'the window itself) and cannot tell positions apart; choose others')


@dataclass(frozen=True)
class FusionConfig(Config):
    """How the cues' likelihoods are fused: eqs. (14), (15), the switch of eq. (18) and Table 8."""

    mode: str = setting('af', 'af: adaptive (eq. 18), mf: multiplicative (eq. 15), wf: weighted with fuzzy '
                        'weights (eq. 14, Tables 8-9)', choices=FUSION_MODES)
    thresholds: tuple[float, ...] = setting((0.0,), 'T_i of eq. (18): cue i is reliable when it concentrates the '
                                            'particles at least this many times (Delta_0 / Delta_i, eq. 17, relative '
                                            'to their unweighted spread); 0 = the cue\'s calibrated value '
                                            '(sonar_tracking.core.gpf.cues); one value for every cue or one per cue',
                                            low=0.0, high=1e6)
    switch: str = setting('crossing', 'how af chooses: cues = eq. (18) alone (every cue reliable -> MF); crossing = '
                          'eq. (18), but WF while another track\'s prediction is inside the particle cloud '
                          '(sonar_tracking.core.gpf.fusion)', choices=FUSION_SWITCHES)
    gate: float = setting(9.21, 'switch crossing: another track is inside the cloud when its predicted position is '
                          'within this squared Mahalanobis distance of the track\'s prediction (9.21: 99 %)',
                          low=0.0, high=1e6, low_open=True)

    def validate(self) -> None:
        if not self.thresholds:
            raise ConfigError('fusion.thresholds is empty: give one T_i for all cues or one per cue')

    def per_cue(self, m: int) -> tuple[float, ...]:
        """The thresholds of ``m`` cues; ConfigError if their number fits neither 1 nor ``m``."""
        if len(self.thresholds) == 1:
            return self.thresholds * m
        if len(self.thresholds) != m:
            raise ConfigError(f'fusion.thresholds has {len(self.thresholds)} values for {m} cues: give one or {m}')
        return self.thresholds


@dataclass(frozen=True)
class BirthConfig(Config):
    """Step 1 of §4.2.3: tracks start on regions that no track explains."""

    sigma_cross: float = setting(math.sqrt(PAPER_INITIAL_VARIANCE_PX[0]) * PAPER_PIXEL,
                                 'initial position std across the line of sight: the paper\'s variance of 45 px^2 '
                                 'read with 0.1 m pixels', unit='m', low=0.0, high=1e3, low_open=True)
    sigma_range: float = setting(math.sqrt(PAPER_INITIAL_VARIANCE_PX[1]) * PAPER_PIXEL,
                                 'initial position std along the line of sight: the paper\'s 40 px^2 read with '
                                 '0.1 m pixels', unit='m', low=0.0, high=1e3, low_open=True)
    sigma_speed: float = setting(0.3, 'initial velocity std per axis, mean zero (ours)', unit='m/s', low=0.0,
                                 high=100.0, low_open=True)
    gate: float = setting(11.8, 'a track explains its nearest region when their squared Mahalanobis distance '
                          '(track position covariance + the initial spread) is below this (11.8: 99.7 %)',
                          low=0.0, high=1e6, low_open=True)
    separation: float = setting(1.0, 'a track also explains every region closer than this to its estimate '
                                '(fragments of its target)', unit='m', low=0.0, high=1e4)
    confirm_hits: int = setting(2, 'frames in which a track sees its target with a region at it (an independent '
                                'detection), birth included, to confirm it', low=1, high=1000)
    max_tracks: int = setting(100, 'no more births beyond this many tracks', low=1, high=100000)


@dataclass(frozen=True)
class LostConfig(Config):
    """Step 3 of §4.2.3: a track that does not see its target widens, and ends after a while."""

    distinct: float = setting(1.0, 'a template is trackable when its mean (d_i / sigma_i)^2 to the frame\'s background '
                              '(the median window) exceeds this; a track whose template looks like background sees '
                              'nothing (ours)', low=0.0, high=1e6)
    ratio: float = setting(0.5, 'the target is seen when the mean (d_i / sigma_i)^2 between the template and the '
                           'window at the estimate is below this fraction of the template\'s distance to the '
                           'background (ours)', low=0.0, high=1.0, low_open=True)
    inflation: float = setting(1.5, 'covariance multiplied by this in each frame the target is not seen',
                               low=1.0, high=100.0)
    refind_sigma: float = setting(0.65, 'position std of a region that a lost track takes up (ours: about the '
                                  'initial spread; tighter values snap to the centroid and disturb the velocity)',
                                  unit='m', low=0.0, high=100.0, low_open=True)
    refind_gate: float = setting(6.0, 'a lost track takes up a free region when their squared Mahalanobis distance '
                                 '(widened track covariance + the initial spread) is below this (6: 95 %; ours)',
                                 low=0.0, high=1e6, low_open=True)
    max_std: float = setting(1.5, 'a miss inflates the covariance only up to this position std (ours: a tank target '
                             'drifts about that far from its predicted path in 20 s); the prediction still spreads '
                             'with the velocity\'s uncertainty', unit='m', low=0.0, high=1e4, low_open=True)
    max_time: float = setting(30.0, 'a confirmed track ends after this long without seeing its target (ours: six '
                              '5 s tank frames, long enough to coast through a crossing while a target hardly '
                              'echoes)', unit='s', low=0.0, high=1e6)
    tentative_time: float = setting(6.0, 'a tentative track ends after this long without seeing its target '
                                    '(0: at its first miss)', unit='s', low=0.0, high=1e6)
    outside_time: float = setting(2.0, 'a track ends once its estimate has been outside the sonar\'s coverage (no '
                                  'pixel with data in its window: outside the fan or the image) this long (ours: '
                                  'two 5 s tank frames, or 2 s of a 10 Hz imaging sonar; 0: at the first such '
                                  'frame)', unit='s', low=0.0, high=1e6)


@dataclass(frozen=True)
class TemplateConfig(Config):
    """The template S_m of eq. (13) and when it follows the target's changing appearance (ours)."""

    rate: float = setting(0.2, 'template <- (1 - rate) template + rate features at the estimate; 0 = keep the '
                          'birth template', low=0.0, high=1.0)
    match: float = setting(2.0, 'update only when the mean (d_i / sigma_i)^2 at the estimate is below this',
                           low=0.0, high=1e6, low_open=True)
    guard: float = setting(2.5, 'no update while another track\'s estimate is closer than this: crossing targets '
                           'would blend their templates', unit='m', low=0.0, high=1e4)


@dataclass(frozen=True)
class GpfConfig(Config):
    """All settings of the GPF tracker (dotted names: ``fusion.mode``)."""

    particles: int = setting(300, 'particles K per track and frame (paper: 300 in the tank, 200 at sea)',
                             low=10, high=100000)
    min_std: float = setting(0.5, 'posterior position std floor of the GPF, and the spread the SIR baseline is '
                             'roughened to after resampling (ours): a sharper posterior leaves the next prediction '
                             'too narrow to hold a towed target that changes course (0.5: best of 0.25-0.65 on the '
                             'tank situations, docs/experiments)', unit='m', low=0.0, high=100.0)
    motion: MotionConfig = dataclasses.field(default_factory=MotionConfig)
    cues: CueConfig = dataclasses.field(default_factory=CueConfig)
    fusion: FusionConfig = dataclasses.field(default_factory=FusionConfig)
    birth: BirthConfig = dataclasses.field(default_factory=BirthConfig)
    lost: LostConfig = dataclasses.field(default_factory=LostConfig)
    template: TemplateConfig = dataclasses.field(default_factory=TemplateConfig)

    def describe(self) -> str:
        """One line saying how the tracker is set up (for a log)."""
        return (f'GPF with K = {self.particles} particles, cues {list(self.cues.numbers)} in {self.cues.window:g} m '
                f'windows, fusion {self.fusion.mode} (T_i {list(self.fusion.thresholds)}), tracks end '
                f'{self.lost.max_time:g} s after losing their target')

    def validate(self) -> None:
        self.fusion.per_cue(len(self.cues.features))

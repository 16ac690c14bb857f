"""The active-sonar detection stage (ESC paper Figure 2): threshold, convert, SCMDE, ESC.

For each sector (one scan of the harbour sonar):

0. the sector's values become linear echo amplitude (``intensity``: decoding of 8-bit dB counts,
   power or display values, noise floor, near-range blanking, maximum range), by
   :func:`sonar_tracking.core.intensity.condition`; the default takes the simulator's linear
   amplitude as it is;
1. every cell above the threshold ``tau`` becomes a detection at its cell centre, or (``cells.grouping
   = connected``, and within ``cells.merge_bins`` x ``merge_beams``) every group of cells one
   detection at its amplitude-weighted centroid (:mod:`.cells`).
   With ``threshold.method`` ``ca``, ``go`` or ``os`` (imaging sonars) the test is CFAR instead
   (:mod:`.cfar`): the intensity (amplitude squared) of each cell over the level of its training
   cells, against the scale ``alpha``, which then is the threshold ESC moves (from the design value
   of ``cfar.pfa``); groups and centroids are taken on that normalised image, a detection's
   amplitude is its largest cell amplitude;
2. echoes of static structure are dropped (``structure``, :mod:`sonar_tracking.core.structure`):
   connected echoes that are too long, too wide, too large or elongated, and those lying on cells
   that echo persistently (a background learnt online from every scan's above-threshold cells);
3. at most ``cells.max_detections`` remain, the strongest (peak amplitude, or peak CFAR ratio); how many were cut is in
   the :class:`ScanResult`;
4. range and bearing are converted to the world frame with ``R = J W J^T`` (eqs. 8-10) or the
   unbiased conversion of ref. [23] (:mod:`.conversion`). ``W`` uses ``sigma_r`` and
   ``sigma_theta``; left at 0 they are the standard deviation of a position uniform in one
   resolution cell, ``cell / (2 sqrt 3)``, which is the harbour sonar's measurement noise. A
   detection spanning ``L_r`` bins and ``L_b`` beams is uniform over that extent instead:
   ``sigma_r^2 + (L_r^2 - 1) dr^2 / 12`` (and likewise in bearing), which is ``(L_r dr)^2 / 12``
   with the default ``sigma_r``; a single cell keeps ``sigma_r`` exactly. With ``cells.target_size``
   L > 0 both standard deviations are at least ``L / (2 sqrt 3)`` (in range, and across at the
   detection's range): the rule for an extended target that breaks into several blobs. Each blob
   stays a detection, spread over the target, so all fall into the target track's gate, start no
   track there (``init.exclude: all``) and are weighed by the track's association, instead of being
   merged over a distance that would also merge neighbouring small targets;
5. each detection gets its clutter density by SCMDE (:mod:`.scmde`) over the sector window. When
   ``max_detections`` cut some, the strongest detections are not a Poisson sample of the scan, so
   every detection gets the count estimate instead: all detections found / window area (the SCMDE
   module's own fallback, unbiased for Poisson counts). With ``scmde.uniform_over = cells`` the
   clutter is uniform over range and bearing (a CFAR's false alarms), per m^2 falling as 1/range;
6. the ESC (:mod:`.esc`) takes the scan's density -- the mean SCMDE density over the whole
   sector, or (``esc.density_source = best_track``, Scenario 2) the density around the confirmed
   track with the highest existence probability -- and sets the threshold of the next scan; with
   ``esc.period`` N > 1 it takes the mean density of N scans and updates once every N scans (an
   imaging sonar at 20 frames a second sees too few false detections in one frame to measure a
   density). With ``esc.exclude_radius`` r > 0 the scan's density is instead the count of the
   detections farther than r from every confirmed track over the window's area outside those discs:
   at frame rate a target's own detections are as many as the false ones and would otherwise raise
   the threshold until the target is lost. ``esc.exclude_existence`` p < 1 counts tracks not yet
   confirmed with existence at least p among those tracks: where several targets appear at once (a
   school), those the tracker has not confirmed yet would otherwise be most of the density.
   Around the track, the density is the number of detections within ``esc.local_radius`` divided
   by the area of that disc inside the sector: an average of the detections' own SCMDE values
   would be dominated by a denser neighbouring region (it has more detections, each with a high
   density) and keep the threshold high in the sparse region the track is in.

Structure is not clutter in the ESC sense (it is there every scan, and the tracker never sees it),
so the density ESC controls is that of the detections left after step 2.

The threshold is one number per scan, as in the paper. Each sector is taken as one scan; for a
SeaKing that publishes a sweep in several sectors, ESC would update once per sector.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.detection.cells import CellDetections, threshold_cells
from sonar_tracking.core.detection.cfar import CFAR_METHODS, Cfar, CfarConfig
from sonar_tracking.core.detection.conversion import convert_measurements
from sonar_tracking.core.detection.esc import ERROR_LAWS, ExtremumSeekingController
from sonar_tracking.core.detection.scmde import PolarWindow, cell_count_density, scmde, scmde_cells, sunflower
from sonar_tracking.core.intensity import IntensityConfig, condition, zero_floor
from sonar_tracking.core.records import DETECTION_DTYPE
from sonar_tracking.core.sector import GeometryError, SectorError, SectorGeometry, check_sector
from sonar_tracking.core.structure import (
    SectorBackground,
    StructureConfig,
    WarmUp,
    echo_shapes,
    is_structure_shape,
    vetoed_groups,
)

__all__ = ['ThresholdConfig', 'CellConfig', 'ScmdeConfig', 'EscConfig', 'DetectorConfig', 'ActiveDetector',
           'ScanResult', 'DetectionInputError', 'best_track_focus', 'tracked_positions']

_SQRT12 = 2.0 * math.sqrt(3.0)
_DISC = sunflower(256)


def _extent_sigma(sigma: float, span: np.ndarray, step: float) -> float | np.ndarray:
    """Std of a position uniform over ``span`` cells of ``step``: ``sigma^2 + (span^2 - 1) step^2 / 12``
    (``sigma`` itself, exactly, for single cells)."""
    if not np.any(span > 1):
        return sigma
    return np.where(span > 1, np.sqrt(sigma * sigma + (span * span - 1.0) * step * step / 12.0), sigma)


class DetectionInputError(ValueError):
    """A sector cannot be processed (the sector rule of :func:`~sonar_tracking.core.sector.check_sector`:
    wrong shape, not numbers, NaN, infinite or negative values); it should be dropped."""


@dataclass(frozen=True)
class ThresholdConfig(Config):
    """Detection threshold: on the echo amplitude, or the scale of a CFAR test."""

    method: str = setting('fixed', "'fixed': one threshold tau on the amplitude of every cell (ESC paper); 'ca', "
                          "'go', 'os': CFAR on the intensity (cell-averaging, greatest-of, ordered-statistic; see "
                          'cfar.*), the threshold is the CFAR scale alpha, starting from the design value of '
                          'cfar.pfa', choices=('fixed',) + CFAR_METHODS)
    initial: float = setting(3.0, 'initial threshold tau_0 (the fixed threshold when ESC is off); CFAR methods '
                             'start from the scale of cfar.pfa instead', low=0.0, low_open=True, high=1e6)
    minimum: float = setting(0.5, 'lowest threshold (or CFAR scale) ESC may set', low=0.0, low_open=True, high=1e6)
    maximum: float = setting(30.0, 'highest threshold (or CFAR scale) ESC may set', low=0.0, low_open=True,
                             high=1e6)

    def validate(self) -> None:
        if self.method != 'fixed':      # CFAR starts from the scale of cfar.pfa (checked by DetectorConfig)
            if not self.minimum <= self.maximum:
                raise ConfigError(f'needs threshold.minimum <= threshold.maximum, not {self.minimum} <= {self.maximum}')
            return
        if not self.minimum <= self.initial <= self.maximum:
            raise ConfigError('needs threshold.minimum <= threshold.initial <= threshold.maximum, not '
                              f'{self.minimum} <= {self.initial} <= {self.maximum}')


@dataclass(frozen=True)
class CellConfig(Config):
    """How cells become detections."""

    grouping: str = setting('cells', "'cells': every cell above threshold is a detection (ESC paper; joined only "
                            "within merge_bins x merge_beams); 'connected': one detection per connected group of "
                            'cells above threshold', choices=('cells', 'connected'))
    merge_bins: int = setting(1, 'resolution cell depth in image rows: cells above threshold nearer than this are '
                              'one echo', low=1, high=64)
    merge_beams: int = setting(1, 'resolution cell width in image columns', low=1, high=64)
    max_detections: int = setting(2000, 'at most this many detections per scan, the strongest (peak amplitude); the '
                                  'number cut is reported', low=1, high=1_000_000)
    sigma_r: float = setting(0.0, 'range std of a detection; 0 = range bin / (2 sqrt 3)', unit='m', low=0.0, high=1e4)
    sigma_theta_deg: float = setting(0.0, 'bearing std of a detection; 0 = beam step / (2 sqrt 3)', unit='deg',
                                     low=0.0, high=45.0)
    target_size: float = setting(0.0, 'extended targets: a detection is taken as uniform over at least this length '
                                 'in range and across, so its position std is at least target_size / (2 sqrt 3) '
                                 '(which part of a diver crosses the threshold changes frame to frame); 0 = off',
                                 unit='m', low=0.0, high=1e4)
    conversion: str = setting('linearized', "polar to Cartesian: 'linearized' (eqs. 8-10) or 'unbiased' (ref. 23)",
                              choices=('linearized', 'unbiased'))


@dataclass(frozen=True)
class ScmdeConfig(Config):
    """Spatial clutter measurement density estimation."""

    order: int = setting(6, 'nearest neighbours that define each detection\'s volume', low=3, high=100)
    edge_correction: bool = setting(True, 'count only the part of each volume inside the sector window')
    uniform_over: str = setting('area', 'what clutter is uniform over: the sea\'s area (the papers) or the polar '
                                'image\'s range-bearing cells (a CFAR\'s false alarms: per m^2 falling as 1/range)',
                                choices=('area', 'cells'))


@dataclass(frozen=True)
class EscConfig(Config):
    """Extremum seeking control of the threshold (§3)."""

    enabled: bool = setting(True, 'adapt the threshold by ESC; off = keep threshold.initial')
    desired_clutter_density: float = setting(2.21e-5, 'rho_D; 0 = look it up in the desired-density table for '
                                             'esc.snr_db', unit='1/m^2', low=0.0, high=1.0)
    snr_db: float = setting(8.0, 'target SNR for the desired-density table lookup', unit='dB', low=-20.0, high=60.0)
    dither_amplitude: float = setting(0.1, 'A_max as a fraction of tau_0 (eq. 45)', low=0.0, high=1.0)
    dither_decay: float = setting(0.9, 'd of eq. (45)', low=0.0, high=1.0)
    gain: float = setting(0.15, 'integrator gain (forward-Euler step per scan); see core/detection/esc.py',
                          low=0.0, low_open=True, high=10.0)
    error: str = setting('inverse', "ESC error law: 'inverse', the paper's compandor on 1/rho_k - 1/rho_D (eqs. 43, "
                         "46), or 'linear', a step proportional to rho_k / rho_D - 1, which settles on rho_D also "
                         "when the density is noisy (few detections per update); see core/detection/esc.py",
                         choices=ERROR_LAWS)
    density_source: str = setting('sector', "ESC input: mean density of the 'sector' or near the 'best_track'",
                                  choices=('sector', 'best_track'))
    local_radius: float = setting(200.0, 'best_track: the density is measured in a disc of this radius around the '
                                  'track', unit='m', low=0.0, low_open=True, high=1e5)
    exclude_radius: float = setting(0.0, 'detections within this distance of a confirmed track are its target\'s, not '
                                    'clutter: the ESC input is then the count of the other detections over the window '
                                    'area outside those discs (0 = every detection counts, as in the paper; needed '
                                    'where a frame holds about as many false detections as targets)', unit='m',
                                    low=0.0, high=1e5)
    exclude_existence: float = setting(1.0, 'esc.exclude_radius also around tracks not yet confirmed whose '
                                       'existence is at least this (1 = confirmed tracks only; where targets are '
                                       'several and false detections few, the targets a track has not confirmed '
                                       'yet would be most of what ESC counts)', low=0.0, low_open=True, high=1.0)
    period: int = setting(1, 'scans per ESC update: ESC sees the mean density of this many scans (1: every scan, as '
                          'in the paper; imaging sonars see too few false detections in one frame)', low=1, high=10000)


@dataclass(frozen=True)
class DetectorConfig(Config):
    """All settings of the detection stage."""

    intensity: IntensityConfig = dataclasses.field(default_factory=IntensityConfig)
    threshold: ThresholdConfig = dataclasses.field(default_factory=ThresholdConfig)
    cells: CellConfig = dataclasses.field(default_factory=CellConfig)
    scmde: ScmdeConfig = dataclasses.field(default_factory=ScmdeConfig)
    esc: EscConfig = dataclasses.field(default_factory=EscConfig)
    structure: StructureConfig = dataclasses.field(default_factory=StructureConfig)
    cfar: CfarConfig = dataclasses.field(default_factory=CfarConfig)

    def validate(self) -> None:
        t = self.threshold
        if t.method == 'fixed':
            return
        alpha0 = Cfar(t.method, self.cfar).alpha0
        if not t.minimum <= alpha0 <= t.maximum:
            raise ConfigError(f'cfar.pfa = {self.cfar.pfa:g} gives {t.method} CFAR the scale {alpha0:.4g}, outside '
                              f'threshold.minimum .. threshold.maximum = {t.minimum:g} .. {t.maximum:g}')


@dataclass(frozen=True, eq=False)
class ScanResult:
    """One processed sector."""

    detections: np.ndarray   # DETECTION_DTYPE
    threshold: float         # threshold applied to this scan
    mean_density: float      # the density ESC saw (sector or local mean) [1/m^2]
    next_threshold: float    # threshold for the next scan
    found: int = 0           # detections found before structure rejection and the max_detections cut
    structure: int = 0       # of those, dropped as static structure (shape gates or persistent echo)
    cut: int = 0             # of the rest, dropped by cells.max_detections (the weakest)
    held: bool = False       # the structure background is warming up: no detection is output

    def summary(self) -> dict[str, str]:
        """The scan's figures as text (a diagnostics report)."""
        return {'threshold': f'{self.threshold:.4f}', 'next_threshold': f'{self.next_threshold:.4f}',
                'clutter_density': f'{self.mean_density:.4g}', 'detections': str(len(self.detections)),
                'found': str(self.found), 'structure': str(self.structure), 'cut_max_detections': str(self.cut)}


class ActiveDetector:
    """Threshold + SCMDE + ESC on successive sectors.

    ``desired_density`` is rho_D already resolved (from the config or the table); required when
    ``config.esc.desired_clutter_density`` is 0.
    """

    def __init__(self, config: DetectorConfig, desired_density: float | None = None) -> None:
        rho_d = desired_density if desired_density is not None else config.esc.desired_clutter_density
        if not rho_d > 0:
            raise ConfigError('esc.desired_clutter_density is 0 (table lookup) but no table value was given')
        self.config = config
        self.desired_density = float(rho_d)
        t, e = config.threshold, config.esc
        self.cfar = None if t.method == 'fixed' else Cfar(t.method, config.cfar)
        tau0 = t.initial if self.cfar is None else self.cfar.alpha0
        self.esc = ExtremumSeekingController(self.desired_density, tau0, t.minimum, t.maximum,
                                             e.dither_amplitude, e.dither_decay, e.gain, e.error)
        self._enabled = e.enabled
        self.background = SectorBackground(config.structure)
        self.warmup = WarmUp()
        self.scans = 0
        self.last_density = math.nan
        self._clock = 0.0
        self._densities: list[float] = []   # of the scans since the last ESC update

    @property
    def threshold(self) -> float:
        """Threshold for the next scan (frozen while ESC is off)."""
        return self.esc.threshold

    @property
    def enabled(self) -> bool:
        """Whether ESC adapts the threshold; switching off freezes it where it is."""
        return self._enabled

    @enabled.setter
    def enabled(self, on: bool) -> None:
        if on and not self._enabled:
            # Resume from the frozen threshold, without the dither's jump.
            self.esc.state.integrator = self.esc.state.threshold
            self._densities = []
        self._enabled = bool(on)

    def reconfigure(self, config: DetectorConfig) -> None:
        """Apply settings that need no restart of ESC: ``intensity``, ``structure`` (a change starts
        an empty background) and ``cells.max_detections``. Any other change raises ValueError:
        build a new detector (ESC starts again from tau_0)."""
        old = self.config
        same = dataclasses.replace(config, intensity=old.intensity, structure=old.structure,
                                   cells=dataclasses.replace(config.cells, max_detections=old.cells.max_detections))
        if same != old:
            raise ValueError('threshold, cell, SCMDE or ESC settings changed: make a new ActiveDetector')
        self.config = config
        if config.structure != old.structure:
            self.background = SectorBackground(config.structure)
            self.warmup.reset()

    def reset(self) -> None:
        """Back to tau_0 and scan 0, with an empty structure background."""
        self.esc.reset()
        self.background.reset()
        self.warmup.reset()
        self.scans = 0
        self.last_density = math.nan
        self._clock = 0.0
        self._densities = []

    def state(self) -> dict:
        """JSON-ready state: threshold, density, scan count and ESC internals."""
        s = self.esc.state
        return {'threshold': self.threshold,
                'clutter_density': None if math.isnan(self.last_density) else self.last_density,
                'desired_clutter_density': self.desired_density, 'scan_count': self.scans,
                'esc_enabled': self.enabled, 'esc_step': s.k, 'esc_integrator': s.integrator}

    def process(self, amplitudes: np.ndarray, geometry: SectorGeometry,
                pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
                focus_xy: tuple[float, float] | None = None, stamp: float | None = None,
                tracked_xy: np.ndarray | None = None) -> ScanResult:
        """Detect in one sector taken from ``pose`` (sensor x, y, yaw in the world frame).

        ``amplitudes`` are the sensor's values (bins x beams, any numeric dtype), decoded by
        ``intensity``. ``focus_xy``: world position of the best track, used when
        ``esc.density_source`` is ``best_track`` (the sector mean is used while there is none).
        ``tracked_xy``: ``(K, 2)`` world positions of the confirmed tracks, whose detections ESC
        leaves out with ``esc.exclude_radius`` > 0 (non-finite rows are ignored).
        ``stamp`` [s] times the structure background; without it scans are ``geometry.scan_time``
        (1 s if 0) apart. Raises DetectionInputError for a sector that cannot be used (nothing
        changes then).
        """
        cfg = self.config
        try:
            raw = check_sector(amplitudes, geometry, cfg.intensity.coding)
        except (SectorError, GeometryError) as exc:
            raise DetectionInputError(str(exc)) from None
        if stamp is not None and not math.isfinite(stamp):
            raise DetectionInputError(f'stamp {stamp} is not finite')
        if not all(map(math.isfinite, pose)):
            raise DetectionInputError(f'sonar pose {pose} is not finite')
        a, geometry = condition(raw, geometry, cfg.intensity)
        if raw.dtype.kind == 'f':
            a = a.astype(raw.dtype, copy=False)  # tau is compared at the sensor's float precision
        t = self._time(stamp, geometry)
        tau = self.threshold
        # CFAR tests the intensity against its training cells: the normalised image against the scale.
        if self.cfar is None:
            test = a
        else:
            floor = zero_floor(cfg.intensity, raw.dtype)
            test = self.cfar.normalise(np.square(a, dtype=np.float32), floor * floor)
        cells = threshold_cells(test, tau, cfg.cells.merge_bins, cfg.cells.merge_beams,
                                cfg.cells.grouping == 'connected', echoes=cfg.structure.enabled)
        peak = cells.amplitude if self.cfar is None else _group_peaks(a, cells)
        found = len(cells)
        keep = np.arange(found)
        if cfg.structure.enabled:
            keep = np.flatnonzero(~self._structure(cells, geometry, pose, t))
        n_structure = found - len(keep)
        cut = max(0, len(keep) - cfg.cells.max_detections)
        if cut:
            strongest = np.argsort(-cells.amplitude[keep], kind='stable')[:cfg.cells.max_detections]
            keep = np.sort(keep[strongest])
        dr = geometry.range_resolution if geometry.n_bins > 1 else 1.0
        r = geometry.range_min + cells.rows[keep] * dr
        b = geometry.angle_min + cells.cols[keep] * geometry.angle_increment
        sigma_r = cfg.cells.sigma_r or dr / _SQRT12
        sigma_b = math.radians(cfg.cells.sigma_theta_deg) or geometry.angle_increment / _SQRT12
        sigma_rs = _extent_sigma(sigma_r, cells.span_rows[keep], dr)
        sigma_bs = _extent_sigma(sigma_b, cells.span_cols[keep], geometry.angle_increment)
        if cfg.cells.target_size > 0:
            floor = cfg.cells.target_size / _SQRT12
            sigma_rs = np.maximum(sigma_rs, floor)
            sigma_bs = np.maximum(sigma_bs, floor / np.maximum(r, dr))
        xy, cov = convert_measurements(r, b, sigma_rs, sigma_bs, pose, cfg.cells.conversion == 'unbiased')
        r_hi = geometry.range_max + dr / 2
        r_lo = min(max(0.0, geometry.range_min - dr / 2, cfg.intensity.blank_range), r_hi)
        window = PolarWindow(r_lo, r_hi,
                             geometry.angle_min - geometry.angle_increment / 2,
                             geometry.angle_max + geometry.angle_increment / 2)
        r_floor = max(window.r_min, 0.5 * dr)
        if cut:
            # The strongest detections are no Poisson sample: the count estimate of every detection.
            rho = (cell_count_density(found - n_structure, r, window, r_floor)
                   if cfg.scmde.uniform_over == 'cells' else np.full(len(keep), (found - n_structure) / window.area))
        else:
            rho = self._scmde(r, b, window, r_floor)
        density = self._esc_input(xy, rho, focus_xy, pose, window, tracked_xy)
        self.last_density = density
        self.scans += 1
        if self.enabled:
            self._densities.append(density)
            if len(self._densities) >= cfg.esc.period:
                self.esc.update(float(np.mean(self._densities)))
                self._densities.clear()
        rec = np.zeros(len(keep), DETECTION_DTYPE)
        rec['x'], rec['y'] = xy[:, 0], xy[:, 1]
        rec['range'], rec['bearing'], rec['amplitude'] = r, b, peak[keep]
        rec['clutter_density'] = rho
        rec['cov_xx'], rec['cov_xy'], rec['cov_yy'] = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
        held = self.warmup.holding(t, cfg.structure)    # ESC and the background learn; nothing goes out
        return ScanResult(rec[:0] if held else rec, tau, density, self.threshold, found=found,
                          structure=n_structure, cut=cut, held=held)

    def _scmde(self, r: np.ndarray, b: np.ndarray, window: PolarWindow, r_floor: float) -> np.ndarray:
        """Each detection's clutter density by SCMDE, over area or over cells (``scmde.uniform_over``)."""
        sc = self.config.scmde
        if sc.uniform_over == 'cells':
            return scmde_cells(r, b, sc.order, window, r_floor, sc.edge_correction)
        sensor_xy = np.stack([r * np.cos(b), r * np.sin(b)], axis=-1)
        return scmde(sensor_xy, sc.order, window if sc.edge_correction else None)

    def _time(self, stamp: float | None, geometry: SectorGeometry) -> float:
        """The scan's time for the structure background: the stamp, or the scan count's clock."""
        if stamp is not None:
            return float(stamp)
        t = self._clock
        self._clock += geometry.scan_time or 1.0
        return t

    def _structure(self, cells: CellDetections, geometry: SectorGeometry, pose: tuple[float, float, float],
                   t: float) -> np.ndarray:
        """Which detections are static structure (see :mod:`sonar_tracking.core.structure`); the
        background then learns this scan's above-threshold cells."""
        sc = self.config.structure
        n = cells.n_echoes
        structure = np.zeros(n, bool)
        if sc.shape_gates and n:
            dr = geometry.range_resolution if geometry.n_bins > 1 else 1.0
            r = geometry.range_min + dr * cells.cell_rows
            b = geometry.angle_min + geometry.angle_increment * cells.cell_cols
            c, s = np.cos(b), np.sin(b)
            across = np.maximum(r, 0.5 * dr) * geometry.angle_increment
            vr, vt = dr * dr / 12.0, across * across / 12.0
            length, width, area = echo_shapes(r * c, r * s, cells.cell_echo, n, c * c * vr + s * s * vt,
                                              c * s * (vr - vt), s * s * vr + c * c * vt, dr * across)
            structure |= is_structure_shape(length, width, area, sc)
        if sc.persistence_veto:
            on = self.background.persistent(cells.cell_rows, cells.cell_cols, geometry, pose, t)
            structure |= vetoed_groups(cells.cell_echo, n, on, sc.veto_fraction)
            echo = np.zeros(geometry.shape, bool)
            echo[cells.cell_rows, cells.cell_cols] = True
            self.background.update(echo, geometry, pose, t)
        drop = np.zeros(len(cells), bool)
        hit = structure[cells.cell_echo]
        drop[cells.cell_group[hit]] = True
        return drop

    def _esc_input(self, xy: np.ndarray, rho: np.ndarray, focus_xy, pose, window: PolarWindow,
                   tracked_xy: np.ndarray | None = None) -> float:
        esc = self.config.esc
        if esc.exclude_radius > 0 and esc.density_source == 'sector':
            return _untracked_density(xy, tracked_xy, esc.exclude_radius, pose, window)
        if esc.density_source == 'best_track' and focus_xy is not None:
            radius = esc.local_radius
            # The disc's area inside the sector, from the same sunflower points SCMDE uses.
            c, s = math.cos(pose[2]), math.sin(pose[2])
            fx, fy = focus_xy[0] - pose[0], focus_xy[1] - pose[1]
            sx, sy = c * fx + s * fy, -s * fx + c * fy
            inside = float(window.disc_fraction(np.array([sx]), np.array([sy]), np.array([radius]), _DISC)[0])
            if inside > 0:
                near = (xy[:, 0] - focus_xy[0]) ** 2 + (xy[:, 1] - focus_xy[1]) ** 2 <= radius ** 2
                return float(near.sum() / (math.pi * radius ** 2 * inside))
        return float(rho.mean()) if len(rho) else 0.0


def _untracked_density(xy: np.ndarray, tracked_xy: np.ndarray | None, radius: float,
                       pose: tuple[float, float, float], window: PolarWindow) -> float:
    """Detections farther than ``radius`` from every confirmed track, over the window's area outside
    the tracks' discs (the count estimate, unbiased for Poisson clutter)."""
    area = window.area
    tracks = np.zeros((0, 2)) if tracked_xy is None else np.asarray(tracked_xy, dtype=float).reshape(-1, 2)
    tracks = tracks[np.isfinite(tracks).all(axis=1)]
    if not len(tracks):
        return len(xy) / area
    c, s = math.cos(pose[2]), math.sin(pose[2])
    fx, fy = tracks[:, 0] - pose[0], tracks[:, 1] - pose[1]
    inside = window.disc_fraction(c * fx + s * fy, -s * fx + c * fy, np.full(len(tracks), radius), _DISC)
    area = max(area - math.pi * radius * radius * float(np.sum(inside)), 0.05 * area)
    if not len(xy):
        return 0.0
    nearest, _ = cKDTree(tracks).query(xy, k=1)     # memory linear in detections and tracks
    return int(np.count_nonzero(nearest > radius)) / area


def _group_peaks(amplitudes: np.ndarray, cells: CellDetections) -> np.ndarray:
    """The largest amplitude among each detection's cells (CFAR groups cells on the normalised image)."""
    peak = np.zeros(len(cells))
    np.maximum.at(peak, cells.cell_group, amplitudes[cells.cell_rows, cells.cell_cols].astype(float))
    return peak


#: Most confirmed tracks whose detections ESC leaves out (``esc.exclude_radius``); bounds the work per scan.
MAX_TRACKED = 1000


def tracked_positions(tracks: np.ndarray, min_existence: float = 1.0) -> np.ndarray:
    """World positions ``(K, 2)`` of the tracks among ``tracks`` (``x, y, existence, confirmed``
    records) that are confirmed or whose existence is at least ``min_existence`` (``esc.exclude_existence``;
    1: confirmed only), with a finite position: the tracks ``esc.exclude_radius`` keeps ESC's input
    clear of; at most :data:`MAX_TRACKED`, those of highest existence."""
    likely = (tracks['confirmed'] != 0) | (tracks['existence'] >= min_existence)
    ok = tracks[likely & np.isfinite(tracks['x']) & np.isfinite(tracks['y'])]
    if len(ok) > MAX_TRACKED:
        ok = ok[np.argsort(-np.nan_to_num(ok['existence'], nan=-1.0), kind='stable')[:MAX_TRACKED]]
    return np.stack([ok['x'], ok['y']], axis=-1).astype(float).reshape(-1, 2)


def best_track_focus(tracks: np.ndarray) -> tuple[float, float] | None:
    """Where ESC measures the density with ``esc.density_source: best_track`` (§5.2): the position of
    the confirmed track of highest existence among ``tracks`` (``x, y, existence, confirmed``
    records); None without one. Tracks with a non-finite position or existence are passed over."""
    ok = tracks[(tracks['confirmed'] != 0) & np.isfinite(tracks['x']) & np.isfinite(tracks['y'])
                & np.isfinite(tracks['existence'])]
    if not len(ok):
        return None
    best = ok[np.argmax(ok['existence'])]
    return float(best['x']), float(best['y'])

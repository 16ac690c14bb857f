"""The active-sonar detection stage (ESC paper Figure 2): threshold, convert, SCMDE, ESC.

For each sector (one scan of the harbour sonar):

1. every cell above the threshold ``tau`` becomes a detection (:mod:`.cells`), at its cell centre;
2. range and bearing are converted to the world frame with ``R = J W J^T`` (eqs. 8-10) or the
   unbiased conversion of ref. [23] (:mod:`.conversion`). ``W`` uses ``sigma_r`` and
   ``sigma_theta``; left at 0 they are the standard deviation of a position uniform in one
   resolution cell, ``cell / (2 sqrt 3)``, which is the harbour sonar's measurement noise;
3. each detection gets its clutter density by SCMDE (:mod:`.scmde`) over the sector window;
4. the ESC (:mod:`.esc`) takes the scan's density -- the mean SCMDE density over the whole
   sector, or (``esc.density_source = best_track``, Scenario 2) the density around the confirmed
   track with the highest existence probability -- and sets the threshold of the next scan.
   Around the track, the density is the number of detections within ``esc.local_radius`` divided
   by the area of that disc inside the sector: an average of the detections' own SCMDE values
   would be dominated by a denser neighbouring region (it has more detections, each with a high
   density) and keep the threshold high in the sparse region the track is in.

The threshold is one number per scan, as in the paper. Each sector is taken as one scan; for a
SeaKing that publishes a sweep in several sectors, ESC would update once per sector.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..config import Config, ConfigError, setting
from ..records import DETECTION_DTYPE
from ..sector import SectorGeometry
from .cells import threshold_cells
from .conversion import convert_measurements
from .esc import ExtremumSeekingController
from .scmde import PolarWindow, scmde, sunflower

__all__ = ['ThresholdConfig', 'CellConfig', 'ScmdeConfig', 'EscConfig', 'DetectorConfig', 'ActiveDetector',
           'ScanResult', 'DetectionInputError']

_SQRT12 = 2.0 * math.sqrt(3.0)
_DISC = sunflower(256)


class DetectionInputError(ValueError):
    """A sector cannot be processed (non-finite amplitudes, wrong shape); it should be dropped."""


@dataclass(frozen=True)
class ThresholdConfig(Config):
    """Detection threshold on the echo amplitude."""

    initial: float = setting(3.0, 'initial threshold tau_0 (the fixed threshold when ESC is off)',
                             low=0.0, low_open=True, high=1e6)
    minimum: float = setting(0.5, 'lowest threshold ESC may set', low=0.0, low_open=True, high=1e6)
    maximum: float = setting(30.0, 'highest threshold ESC may set', low=0.0, low_open=True, high=1e6)

    def validate(self) -> None:
        if not self.minimum <= self.initial <= self.maximum:
            raise ConfigError(f'threshold.initial = {self.initial} must lie in [threshold.minimum, '
                              f'threshold.maximum] = [{self.minimum}, {self.maximum}]')


@dataclass(frozen=True)
class CellConfig(Config):
    """How cells become detections."""

    merge_bins: int = setting(1, 'resolution cell depth in image rows: nearer cells above threshold are one echo',
                              low=1, high=64)
    merge_beams: int = setting(1, 'resolution cell width in image columns', low=1, high=64)
    sigma_r: float = setting(0.0, 'range std of a detection; 0 = range bin / (2 sqrt 3)', unit='m', low=0.0, high=1e4)
    sigma_theta_deg: float = setting(0.0, 'bearing std of a detection; 0 = beam step / (2 sqrt 3)', unit='deg',
                                     low=0.0, high=45.0)
    conversion: str = setting('linearized', "polar to Cartesian: 'linearized' (eqs. 8-10) or 'unbiased' (ref. 23)",
                              choices=('linearized', 'unbiased'))


@dataclass(frozen=True)
class ScmdeConfig(Config):
    """Spatial clutter measurement density estimation."""

    order: int = setting(6, 'nearest neighbours that define each detection\'s volume', low=3, high=100)
    edge_correction: bool = setting(True, 'count only the part of each volume inside the sector window')


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
    density_source: str = setting('sector', "ESC input: mean density of the 'sector' or near the 'best_track'",
                                  choices=('sector', 'best_track'))
    local_radius: float = setting(200.0, 'best_track: the density is measured in a disc of this radius around the '
                                  'track', unit='m', low=0.0, low_open=True, high=1e5)


@dataclass(frozen=True)
class DetectorConfig(Config):
    """All settings of the detection stage."""

    threshold: ThresholdConfig = dataclasses.field(default_factory=ThresholdConfig)
    cells: CellConfig = dataclasses.field(default_factory=CellConfig)
    scmde: ScmdeConfig = dataclasses.field(default_factory=ScmdeConfig)
    esc: EscConfig = dataclasses.field(default_factory=EscConfig)


@dataclass(frozen=True, eq=False)
class ScanResult:
    """One processed sector."""

    detections: np.ndarray   # DETECTION_DTYPE
    threshold: float         # threshold applied to this scan
    mean_density: float      # the density ESC saw (sector or local mean) [1/m^2]
    next_threshold: float    # threshold for the next scan


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
        self.esc = ExtremumSeekingController(self.desired_density, t.initial, t.minimum, t.maximum,
                                             e.dither_amplitude, e.dither_decay, e.gain)
        self._enabled = e.enabled
        self.scans = 0
        self.last_density = math.nan

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
        self._enabled = bool(on)

    def reset(self) -> None:
        """Back to tau_0 and scan 0."""
        self.esc.reset()
        self.scans = 0
        self.last_density = math.nan

    def state(self) -> dict:
        """JSON-ready state: threshold, density, scan count and ESC internals."""
        s = self.esc.state
        return {'threshold': self.threshold,
                'clutter_density': None if math.isnan(self.last_density) else self.last_density,
                'desired_clutter_density': self.desired_density, 'scan_count': self.scans,
                'esc_enabled': self.enabled, 'esc_step': s.k, 'esc_integrator': s.integrator}

    def process(self, amplitudes: np.ndarray, geometry: SectorGeometry,
                pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
                focus_xy: tuple[float, float] | None = None) -> ScanResult:
        """Detect in one sector taken from ``pose`` (sensor x, y, yaw in the world frame).

        ``focus_xy``: world position of the best track, used when ``esc.density_source`` is
        ``best_track`` (the sector mean is used while there is none).
        """
        a = np.asarray(amplitudes)
        if a.shape != geometry.shape:
            raise DetectionInputError(f'amplitudes have shape {a.shape}, geometry says {geometry.shape}')
        if not np.isfinite(a).all():
            raise DetectionInputError(f'{int((~np.isfinite(a)).sum())} amplitudes are NaN or infinite')
        cfg = self.config
        tau = self.threshold
        cells = threshold_cells(a, tau, cfg.cells.merge_bins, cfg.cells.merge_beams)
        dr = geometry.range_resolution if geometry.n_bins > 1 else 1.0
        r = geometry.range_min + cells.rows * dr
        b = geometry.angle_min + cells.cols * geometry.angle_increment
        sigma_r = cfg.cells.sigma_r or dr / _SQRT12
        sigma_b = math.radians(cfg.cells.sigma_theta_deg) or geometry.angle_increment / _SQRT12
        xy, cov = convert_measurements(r, b, sigma_r, sigma_b, pose, cfg.cells.conversion == 'unbiased')
        window = PolarWindow(max(0.0, geometry.range_min - dr / 2), geometry.range_max + dr / 2,
                             geometry.angle_min - geometry.angle_increment / 2,
                             geometry.angle_max + geometry.angle_increment / 2)
        sensor_xy = np.stack([r * np.cos(b), r * np.sin(b)], axis=-1)
        rho = scmde(sensor_xy, cfg.scmde.order, window if cfg.scmde.edge_correction else None)
        density = self._esc_input(xy, rho, focus_xy, pose, window)
        self.last_density = density
        self.scans += 1
        if self.enabled:
            self.esc.update(density)
        rec = np.zeros(len(cells), DETECTION_DTYPE)
        rec['x'], rec['y'] = xy[:, 0], xy[:, 1]
        rec['range'], rec['bearing'], rec['amplitude'] = r, b, cells.amplitude
        rec['clutter_density'] = rho
        rec['cov_xx'], rec['cov_xy'], rec['cov_yy'] = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
        return ScanResult(rec, tau, density, self.threshold)

    def _esc_input(self, xy: np.ndarray, rho: np.ndarray, focus_xy, pose, window: PolarWindow) -> float:
        esc = self.config.esc
        if esc.density_source == 'best_track' and focus_xy is not None:
            radius = esc.local_radius
            # The disc's area inside the sector, from the same sunflower points SCMDE uses.
            c, s = math.cos(pose[2]), math.sin(pose[2])
            fx, fy = focus_xy[0] - pose[0], focus_xy[1] - pose[1]
            sx, sy = c * fx + s * fy, -s * fx + c * fy
            inside = window.contains(sx + radius * _DISC[:, 0], sy + radius * _DISC[:, 1]).mean()
            if inside > 0:
                near = (xy[:, 0] - focus_xy[0]) ** 2 + (xy[:, 1] - focus_xy[1]) ** 2 <= radius ** 2
                return float(near.sum() / (math.pi * radius ** 2 * inside))
        return float(rho.mean()) if len(rho) else 0.0

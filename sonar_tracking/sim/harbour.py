"""The harbour active sonar of the ESC paper (§2, §5.1): one range-bearing scan per second.

Resolution cells are ``2 * sqrt(3) * sigma_r`` deep in range and ``2 * sqrt(3) * sigma_theta`` wide
in bearing. A target lies uniformly somewhere in its cell, so reporting a detection at the cell
centre gives a range error of standard deviation ``sigma_r`` and a bearing error of
``sigma_theta``: the paper's measurement noise (eqs. 5-7) arises from the quantisation itself.

Every cell's amplitude is drawn from the clutter law with the local rate ``lam`` (eq. 15); the
cell holding a target draws from the target law, exponential with mean ``(1 + SNR) / lam``.
All beams are formed at once, so the sector's ``ping_period`` is 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.fan import fan_extent
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.sim.amplitude import AmplitudeModel
from sonar_tracking.sim.scene import Scene
from sonar_tracking.sim.sensor import SimSector

__all__ = ['HarbourConfig', 'HarbourSonar']

_SQRT12 = 2.0 * math.sqrt(3.0)


@dataclass(frozen=True)
class HarbourConfig(Config):
    """Harbour sonar: measurement noise, surveillance window and scan period."""

    sigma_r: float = setting(5.0, 'range measurement std; cell depth = 2*sqrt(3)*sigma_r', unit='m',
                             low=0.01, high=1000.0)
    sigma_theta_deg: float = setting(0.1, 'bearing measurement std; cell width = 2*sqrt(3)*sigma_theta',
                                     unit='deg', low=0.001, high=10.0)
    range_min: float = setting(1800.0, 'near edge of the surveillance window', unit='m', low=0.0)
    range_max: float = setting(3300.0, 'far edge of the surveillance window', unit='m', low=0.0, high=1e5)
    bearing_min_deg: float = setting(-2.0, 'right edge of the window (bearing, CCW from the sonar x axis)',
                                     unit='deg', low=-180.0, high=180.0)
    bearing_max_deg: float = setting(22.0, 'left edge of the window', unit='deg', low=-180.0, high=180.0)
    scan_period: float = setting(1.0, 'time between scans (the paper: 1 s)', unit='s', low=0.01, high=3600.0)

    def validate(self) -> None:
        if self.range_max - self.range_min < self.cell_depth:
            raise ConfigError(f'harbour.range_max - harbour.range_min must hold at least one cell '
                              f'({self.cell_depth:.3g} m)')
        if math.radians(self.bearing_max_deg - self.bearing_min_deg) < self.cell_width:
            raise ConfigError('harbour.bearing_max_deg - harbour.bearing_min_deg must hold at least one cell')

    @property
    def cell_depth(self) -> float:
        """Range extent of a resolution cell [m]."""
        return _SQRT12 * self.sigma_r

    @property
    def cell_width(self) -> float:
        """Bearing extent of a resolution cell [rad]."""
        return _SQRT12 * math.radians(self.sigma_theta_deg)

    def geometry(self) -> SectorGeometry:
        """The fixed cell grid of every scan."""
        n_bins = int(math.floor((self.range_max - self.range_min) / self.cell_depth + 1e-9))
        n_beams = int(math.floor(math.radians(self.bearing_max_deg - self.bearing_min_deg) / self.cell_width + 1e-9))
        r0 = self.range_min + 0.5 * self.cell_depth
        return SectorGeometry(angle_min=math.radians(self.bearing_min_deg) + 0.5 * self.cell_width,
                              angle_increment=self.cell_width, n_beams=n_beams, range_min=r0,
                              range_max=r0 + (n_bins - 1) * self.cell_depth, n_bins=n_bins,
                              ping_period=0.0, scan_time=self.scan_period)


class HarbourSonar:
    """Produces one whole-window scan per ``scan_period``, starting at ``t = scan_period``."""

    def __init__(self, config: HarbourConfig, amplitude: AmplitudeModel | None = None) -> None:
        self.config = config
        self.amplitude = amplitude or AmplitudeModel()
        self.geometry = config.geometry()
        self.scan_index = 0
        self._lam_cache: tuple[tuple, np.ndarray | float] | None = None
        self._static_cache: tuple[tuple, np.ndarray] | None = None

    def reset(self) -> None:
        """Start again from the first scan."""
        self.scan_index = 0

    @property
    def next_time(self) -> float:
        """Time of the next scan [s]."""
        return (self.scan_index + 1) * self.config.scan_period

    def coverage(self) -> tuple[float, float, float, float]:
        """Sensor-frame bounding box ``(x_min, x_max, y_min, y_max)`` of the surveillance window."""
        return fan_extent(self.geometry)

    def cell_centres(self, pose: tuple[float, float, float]) -> np.ndarray:
        """World coordinates ``(n_bins, n_beams, 2)`` of the cell centres for a sensor pose."""
        g = self.geometry
        r = g.ranges()[:, None]
        b = g.bearings()[None, :] + pose[2]
        return np.stack([pose[0] + r * np.cos(b), pose[1] + r * np.sin(b)], axis=-1)

    def _lam(self, scene: Scene, pose: tuple[float, float, float]) -> np.ndarray | float:
        key = (id(scene), scene.lam, len(scene.regions), pose)
        if self._lam_cache is None or self._lam_cache[0] != key:
            self._lam_cache = (key, scene.lam_at(self.cell_centres(pose)))
        return self._lam_cache[1]

    def next_sector(self, scene: Scene, rng: np.random.Generator) -> SimSector:
        """Simulate the next scan of ``scene``."""
        t = self.next_time
        self.scan_index += 1
        x, y, yaw, _, _ = scene.platform_pose(t)
        pose = (x, y, yaw)
        g = self.geometry
        lam = self._lam(scene, pose)
        lam_cells = np.broadcast_to(lam, g.shape)
        amps = self.amplitude.clutter(lam_cells, rng)
        if scene.targets:
            _, states = scene.truth(t)
            i, j, inside, _, _ = self.cell_of(states[:, :2], pose)
            snr = np.array([tg.snr_db for tg in scene.targets])
            if inside.any():
                ii, jj = i[inside], j[inside]
                echo = self.amplitude.target(lam_cells[ii, jj], snr[inside], rng)
                # The target draw replaces the clutter draw: its mean (1 + SNR) / lam already
                # holds the clutter power. Two targets in one cell: the stronger echo.
                target_amp = np.zeros(g.shape)
                np.maximum.at(target_amp, (ii, jj), echo)
                amps[ii, jj] = target_amp[ii, jj]
        if scene.structure is not None:
            amps += scene.structure.fluctuate(self._static(scene, pose), rng)
        return SimSector(stamp=t, amplitudes=amps.astype(np.float32), geometry=g, pose=pose, end_of_sweep=True)

    def cell_of(self, xy: np.ndarray, pose: tuple[float, float, float]) -> tuple[np.ndarray, ...]:
        """Cell ``(i, j)`` of world points ``(K, 2)``, whether inside the window, their range and unit
        direction from the sonar ``(K, 2)``."""
        g = self.geometry
        x, y, yaw = pose
        dx, dy = xy[:, 0] - x, xy[:, 1] - y
        rng_ = np.hypot(dx, dy)
        brg = np.angle(np.exp(1j * (np.arctan2(dy, dx) - yaw)))
        i = np.floor((rng_ - (g.range_min - 0.5 * self.config.cell_depth)) / self.config.cell_depth).astype(int)
        j = np.floor((brg - (g.angle_min - 0.5 * g.angle_increment)) / g.angle_increment).astype(int)
        inside = (i >= 0) & (i < g.n_bins) & (j >= 0) & (j < g.n_beams)
        return i, j, inside, rng_, np.stack([dx, dy], axis=1) / np.maximum(rng_, 1e-9)[:, None]

    def _static(self, scene: Scene, pose: tuple[float, float, float]) -> np.ndarray:
        """Mean echo of the static structure per cell (re the clutter mean), cached per pose.

        A wall's scatterers carry its level times their spacing: a cell sums them over its width
        ``r * cell_width``, so a wall across the beam fills it with the wall's level; a pile lands
        in one cell with its level.
        """
        st = scene.structure
        key = (id(st), scene.lam, pose)
        if self._static_cache is not None and self._static_cache[0] == key:
            return self._static_cache[1]
        g = self.geometry
        mean = np.zeros(g.shape)
        for part in st.scatterers():
            i, j, inside, r, u = self.cell_of(part.points, pose)
            level = part.response(-u)
            extended = ~np.all(part.normals == 0.0, axis=1)
            level = np.where(extended, level / (np.maximum(r, 1e-9) * self.config.cell_width), level)
            np.add.at(mean, (i[inside], j[inside]), level[inside])
        seabed, ring = st.range_profile(g.ranges())
        rows = np.flatnonzero(seabed)
        if rows.size:
            mean[rows] += seabed[rows, None] * st.texture(self.cell_centres(pose)[rows])
        mean += ring[:, None]
        mean /= scene.lam
        self._static_cache = (key, mean)
        return mean

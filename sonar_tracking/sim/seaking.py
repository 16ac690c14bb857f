"""Tritech SeaKing mechanically scanning sonar (FLS paper §2, Table 1).

The head steps by ``step_deg`` and pings once per step, waiting ``2 R / c`` for the echo plus a
processing time before the next step. In sector mode it sweeps back and forth between the limits
(each limit pinged once per reversal); with a 360 deg span it turns continuously. Pings are
grouped into sectors of ``sector_size`` columns that never straddle a reversal or the end of a
turn; columns are always in increasing bearing, so a sector swept clockwise has its column 0
pinged last and a negative ``ping_period`` (LaserScan ``time_increment`` convention).

Echo intensity of a cell at range ``r`` (linear, after the time-varying gain)::

    I = S * (mu_rev(r) + sum of target and ghost echoes) + E * mu_noise(r)

with ``S`` the clutter law of unit mean (exponential = fully developed speckle, multiplicative)
and ``E`` a unit exponential (additive receiver noise). Losses and gain, in intensity:

* reverberation ~ r^-3 10^(-2 a r / 10), target echoes ~ r^-4 10^(-2 a r / 10), noise constant;
* the TVG multiplies by (r / r_ref)^(tvg / 10) 10^(2 a (r - r_ref) / 10), so with the usual
  30 dB/decade reverberation is flat (mean ``1 / lam``), target echoes fall as 1/r and noise
  grows with range: real SeaKing images darken for targets and get noisy far out.

A target's ``snr_db`` is its echo at the reference range, best aspect, beam centre, relative to
the reverberation mean. Scatterer echoes are spread over beams by a Gaussian main lobe of width
``beam_width_deg`` (-3 dB), over range by the pulse length, and each has a surface multipath ghost
at the longer path ``(r + sqrt(r^2 + 4 d^2)) / 2`` (sonar and target at depth ``d``), weakened by
``ghost_db`` and by the vertical beam pattern at the ghost's elevation. A point echo keeps its full
intensity over the pulse's range extent (a box of ``pulse_length``), as a rectangular pulse does.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.fan import fan_extent
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.sim.amplitude import AmplitudeModel
from sonar_tracking.sim.motion import StaticTrajectory
from sonar_tracking.sim.scene import Scene, Target
from sonar_tracking.sim.sensor import SimSector
from sonar_tracking.sim.structure import RoughShape, Structure

__all__ = ['SeaKingConfig', 'SeaKingSonar', 'SectorPlan', 'MAX_RANGE']

#: Maximum range of each SeaKing model [m] (FLS paper Table 1).
MAX_RANGE = {325.0: 300.0, 675.0: 100.0}
_LN2x4 = 4.0 * math.log(2.0)


@dataclass(frozen=True)
class SeaKingConfig(Config):
    """SeaKing head, beam and propagation settings."""

    frequency_khz: float = setting(675.0, 'model: 325 kHz (3 deg beam, 300 m) or 675 kHz (1.5 deg, 100 m)',
                                   unit='kHz', choices=(325.0, 675.0))
    beam_width_deg: float = setting(1.5, 'horizontal -3 dB beam width', unit='deg', low=0.1, high=30.0)
    vertical_beam_width_deg: float = setting(40.0, 'vertical -3 dB beam width', unit='deg', low=1.0, high=90.0)
    range_max: float = setting(30.0, 'range scale (far edge of the last bin)', unit='m', low=0.5, high=300.0)
    n_bins: int = setting(600, 'range bins per ping', low=2, high=8000)
    step_deg: float = setting(0.9, 'head step angle', unit='deg', low=0.05, high=20.0)
    scan_min_deg: float = setting(-60.0, 'right sector limit (bearing, CCW positive)', unit='deg',
                                  low=-180.0, high=180.0)
    scan_max_deg: float = setting(60.0, 'left sector limit; a 360 deg span turns continuously', unit='deg',
                                  low=-180.0, high=540.0)
    sound_speed: float = setting(1500.0, 'speed of sound', unit='m/s', low=1300.0, high=1700.0)
    processing_time: float = setting(0.01, 'head step and processing time per ping', unit='s', low=0.0, high=1.0)
    absorption_db_per_m: float = setting(0.2, 'sea-water absorption (about 0.2 at 675 kHz, 0.09 at 325 kHz)',
                                         unit='dB/m', low=0.0, high=2.0)
    tvg_db_per_decade: float = setting(30.0, 'time-varying gain spreading law', unit='dB/decade', low=0.0, high=60.0)
    reference_range: float = setting(10.0, 'range at which target SNR and noise level are given', unit='m',
                                     low=0.1, high=300.0)
    noise_db: float = setting(-30.0, 'receiver noise re reverberation at the reference range', unit='dB',
                              low=-150.0, high=40.0)
    ghost_db: float = setting(-8.0, 'surface multipath echo re the direct echo', unit='dB', low=-150.0, high=0.0)
    pulse_length: float = setting(0.1, 'range extent of a point echo', unit='m', low=0.0, high=10.0)
    turn: str = setting('ccw', 'direction the head turns first: ccw (toward larger bearing) or cw; a 360 deg '
                        'span keeps turning that way', choices=('ccw', 'cw'))

    def validate(self) -> None:
        limit = MAX_RANGE[self.frequency_khz]
        if self.range_max > limit:
            raise ConfigError(f'seaking.range_max = {self.range_max} exceeds the {self.frequency_khz:g} kHz '
                              f'SeaKing maximum of {limit:g} m')
        span = self.scan_max_deg - self.scan_min_deg
        if span <= 0 or span > 360.0 + 1e-9:
            raise ConfigError(f'seaking.scan_max_deg - seaking.scan_min_deg = {span:g} must be in (0, 360]')
        if self.step_deg > span:
            raise ConfigError(f'seaking.step_deg = {self.step_deg:g} is larger than the sector span {span:g}')

    @property
    def ping_period(self) -> float:
        """Time between pings: two-way travel to the range scale plus processing [s]."""
        return 2.0 * self.range_max / self.sound_speed + self.processing_time

    @property
    def continuous(self) -> bool:
        """True when the head turns through 360 deg instead of sweeping back and forth."""
        return self.scan_max_deg - self.scan_min_deg >= 360.0 - 1e-9

    @property
    def n_positions(self) -> int:
        """Distinct head positions: per turn (continuous) or limit to limit inclusive (sector)."""
        span = self.scan_max_deg - self.scan_min_deg
        if self.continuous:
            return int(round(360.0 / self.step_deg))
        return int(math.floor(span / self.step_deg + 1e-9)) + 1

    @property
    def sweep_time(self) -> float:
        """Time of one turn (continuous) or one limit-to-limit pass (sector mode) [s]."""
        n = self.n_positions if self.continuous else self.n_positions - 1
        return n * self.ping_period


@dataclass(frozen=True, eq=False)
class SectorPlan:
    """Head positions, bearings [rad] and ping times [s] of one sector, in ping order."""

    positions: np.ndarray
    bearings: np.ndarray
    times: np.ndarray
    direction: int
    end_of_sweep: bool


class SeaKingSonar:
    """The mechanical head and the echo model; produces sectors of up to ``sector_size`` pings."""

    def __init__(self, config: SeaKingConfig, sector_size: int = 10, amplitude: AmplitudeModel | None = None) -> None:
        if sector_size < 1:
            raise ConfigError(f'sector_size = {sector_size} must be >= 1')
        self.config = config
        self.sector_size = sector_size
        self.amplitude = amplitude or AmplitudeModel()
        c = config
        self.dr = c.range_max / c.n_bins
        self.ranges = (np.arange(c.n_bins) + 0.5) * self.dr
        self._tvg_exp = c.tvg_db_per_decade / 10.0
        rel = self.ranges / c.reference_range
        self.reverb_profile = rel ** (self._tvg_exp - 3.0)
        self.noise_profile = 10 ** (c.noise_db / 10) * rel ** self._tvg_exp * \
            10 ** (2 * c.absorption_db_per_m * (self.ranges - c.reference_range) / 10)
        self._static_cache: dict[tuple, np.ndarray] = {}
        self._structure_targets: tuple[object, list[Target]] | None = None
        self.reset()

    def reset(self) -> None:
        """Head back to the right limit turning left (``turn = ccw``), or to the left limit turning
        right (``cw``), at time 0."""
        cw = self.config.turn == 'cw'
        self.position = self.config.n_positions - 1 if cw else 0
        self.direction = -1 if cw else 1
        self.ping_count = 0

    @property
    def next_time(self) -> float:
        """Time of the next ping [s] (the first ping is at one ping period)."""
        return (self.ping_count + 1) * self.config.ping_period

    def coverage(self) -> tuple[float, float, float, float]:
        """Sensor-frame bounding box ``(x_min, x_max, y_min, y_max)`` of all bins between the limits."""
        c = self.config
        half = 0.5 * math.radians(c.step_deg)
        one_beam = SectorGeometry(angle_min=0.0, angle_increment=math.radians(c.step_deg), n_beams=1,
                                  range_min=float(self.ranges[0]), range_max=float(self.ranges[-1]), n_bins=c.n_bins)
        return fan_extent(one_beam, math.radians(c.scan_min_deg) - half, math.radians(c.scan_max_deg) + half)

    def plan(self) -> SectorPlan:
        """Advance the head by up to ``sector_size`` pings: the next sector's positions and times."""
        c = self.config
        last = c.n_positions - 1
        positions, direction, end = [], self.direction, False
        while len(positions) < self.sector_size:
            positions.append(self.position)
            if c.continuous and direction > 0:
                if self.position == last:
                    self.position, end = 0, True
                else:
                    self.position += 1
            elif c.continuous:
                if self.position == 0:
                    self.position, end = last, True
                else:
                    self.position -= 1
            else:
                at_limit = (self.position == last and direction > 0) or (self.position == 0 and direction < 0)
                if at_limit or last == 0:
                    self.direction = -direction
                    self.position = max(0, min(last, self.position + self.direction))
                    end = True
                else:
                    self.position += direction
            if end:
                break
        pos = np.array(positions)
        times = (self.ping_count + 1 + np.arange(len(pos))) * c.ping_period
        self.ping_count += len(pos)
        return SectorPlan(pos, np.radians(c.scan_min_deg + pos * c.step_deg), times, direction, end)

    def render_mean(self, scene: Scene, plan: SectorPlan,
                    targets: list[Target] | None = None) -> tuple[np.ndarray, np.ndarray, tuple]:
        """Mean intensities ``(reverb, echoes)`` of a planned sector, in ping order (bins x pings).

        ``echoes`` sums the echoes and ghosts of ``targets`` (default: all of the scene's); the
        third value is the platform state ``(x, y, yaw, vx, vy)`` at the sector's mid time.
        """
        c = self.config
        n, times, bearings = len(plan.positions), plan.times, plan.bearings
        t_mid = 0.5 * (times[0] + times[-1])
        sx, sy, yaw, svx, svy = scene.platform_pose(t_mid)
        sensor_xy = np.stack([sx + svx * (times - t_mid), sy + svy * (times - t_mid)], axis=1)
        if scene.regions:
            b = bearings[None, :] + yaw
            cells = np.stack([sensor_xy[None, :, 0] + self.ranges[:, None] * np.cos(b),
                              sensor_xy[None, :, 1] + self.ranges[:, None] * np.sin(b)], axis=-1)
            reverb = self.reverb_profile[:, None] / scene.lam_at(cells)
        else:
            reverb = np.broadcast_to(self.reverb_profile[:, None] / scene.lam, (c.n_bins, n))
        echoes = np.zeros((c.n_bins, n))
        for target in scene.targets if targets is None else targets:
            self._add_target(echoes, target, scene, times, t_mid, bearings, sensor_xy, yaw, scene.lam)
        width = int(round(c.pulse_length / self.dr))
        if width > 1 and echoes.any():
            # A point echo lasts the pulse: full intensity over the pulse's range extent.
            echoes = uniform_filter1d(echoes, size=width, axis=0, mode='constant') * width
        return reverb, echoes, (sx, sy, yaw, svx, svy)

    def next_sector(self, scene: Scene, rng: np.random.Generator) -> SimSector:
        """Ping the next sector of ``scene``."""
        c = self.config
        plan = self.plan()
        n = len(plan.positions)
        reverb, echoes, (sx, sy, yaw, svx, svy) = self.render_mean(scene, plan)
        amps = self.amplitude.unit(rng, (c.n_bins, n)) * (reverb + echoes)
        amps += rng.standard_exponential((c.n_bins, n)) * (self.noise_profile[:, None] / scene.lam)
        if scene.structure is not None:
            amps += scene.structure.fluctuate(self.static_mean(scene, plan), rng)
        pp = c.ping_period
        if plan.direction < 0:  # columns in increasing bearing: column 0 was pinged last
            amps, stamp, period, angle_min = amps[:, ::-1], plan.times[-1], -pp, plan.bearings[-1]
        else:
            stamp, period, angle_min = plan.times[0], pp, plan.bearings[0]
        geom = SectorGeometry(angle_min=math.remainder(angle_min, 2 * math.pi),
                              angle_increment=math.radians(c.step_deg), n_beams=n,
                              range_min=float(self.ranges[0]), range_max=float(self.ranges[-1]),
                              n_bins=c.n_bins, ping_period=period, scan_time=c.sweep_time)
        t_mid = 0.5 * (plan.times[0] + plan.times[-1])
        pose_stamp = (sx + svx * (stamp - t_mid), sy + svy * (stamp - t_mid), yaw)
        return SimSector(stamp=float(stamp), amplitudes=np.ascontiguousarray(amps, dtype=np.float32),
                         geometry=geom, pose=pose_stamp, end_of_sweep=plan.end_of_sweep)

    def static_mean(self, scene: Scene, plan: SectorPlan) -> np.ndarray:
        """Mean echo of the scene's static structure and the ringdown in a planned sector (bins x pings).

        Walls and piles go through the beam pattern, pulse and multipath like targets (their levels
        are relative to the background reverberation mean ``1 / lam``, as a target's SNR); the seabed
        band is textured at the cells' world positions. Cached by head positions and platform
        state, so a fixed sonar computes each sector of its sweep once.
        """
        st = scene.structure
        t_mid = 0.5 * (plan.times[0] + plan.times[-1])
        key = (id(st), scene.lam, tuple(plan.positions.tolist()), scene.platform_pose(t_mid))
        hit = self._static_cache.get(key)
        if hit is not None:
            return hit
        if self._structure_targets is None or self._structure_targets[0] is not st:
            self._structure_targets = (st, structure_targets(st, math.radians(self.config.beam_width_deg),
                                                             self.config.reference_range))
        _, mean, (sx, sy, yaw, _, _) = self.render_mean(scene, plan, self._structure_targets[1])
        seabed, ring = st.range_profile(self.ranges)
        rows = np.flatnonzero(seabed)
        if rows.size:
            b = plan.bearings[None, :] + yaw
            r = self.ranges[rows, None]
            cells = np.stack([sx + r * np.cos(b), sy + r * np.sin(b)], axis=-1)
            mean[rows] += seabed[rows, None] * st.texture(cells) / scene.lam
        mean += ring[:, None] / scene.lam
        if len(self._static_cache) >= 1024:  # a moving platform never repeats a key
            self._static_cache.clear()
        self._static_cache[key] = mean
        return mean

    def _add_target(self, echoes: np.ndarray, target: Target, scene: Scene, times: np.ndarray, t_mid: float,
                    bearings: np.ndarray, sensor_xy: np.ndarray, yaw: float, lam_bg: float) -> None:
        """Deposit a target's scatterer echoes and multipath ghosts into ``echoes`` (bins x pings)."""
        c = self.config
        x, y, vx, vy = target.trajectory.state(t_mid)
        heading = target.trajectory.heading(t_mid)
        bw = math.radians(c.beam_width_deg)
        # Quick reject: centre bearing far outside the beams of this sector.
        dx0, dy0 = x - sensor_xy[len(times) // 2, 0], y - sensor_xy[len(times) // 2, 1]
        r0 = math.hypot(dx0, dy0)
        if r0 > c.range_max + target.shape.extent:
            return
        centre = math.atan2(dy0, dx0) - yaw
        margin = 4.0 * bw + (math.atan2(target.shape.extent, r0) if r0 > 0 else math.pi)
        lo, hi = bearings.min() - margin, bearings.max() + margin
        if not _angle_within(centre, lo, hi):
            return
        ch, sh = math.cos(heading), math.sin(heading)
        body = target.shape.points @ np.array([[ch, sh], [-sh, ch]])  # rotate body -> world
        dt = times - t_mid
        pos = np.stack([x + vx * dt, y + vy * dt], axis=1)[:, None, :] + body[None, :, :]  # (P, K, 2)
        d = pos - sensor_xy[:, None, :]
        r = np.hypot(d[..., 0], d[..., 1])
        r = np.maximum(r, 1e-3)
        toward = -d / r[..., None]
        toward_body = np.stack([toward[..., 0] * ch + toward[..., 1] * sh,
                                -toward[..., 0] * sh + toward[..., 1] * ch], axis=-1)
        gain = target.shape.response(toward_body)
        off = np.angle(np.exp(1j * (np.arctan2(d[..., 1], d[..., 0]) - yaw - bearings[:, None])))
        gain = gain * np.exp(-_LN2x4 * (off / bw) ** 2)
        snr = 10 ** (target.snr_db / 10)
        level = snr / lam_bg * gain * (r / c.reference_range) ** (self._tvg_exp - 4.0)
        self._deposit(echoes, r, level)
        depth = scene.depth
        if depth > 0 and c.ghost_db > -150:
            r_ghost = 0.5 * (r + np.sqrt(r * r + 4.0 * depth * depth))
            elev = np.arctan2(2.0 * depth, r)
            vbw = math.radians(c.vertical_beam_width_deg)
            ghost = level * 10 ** (c.ghost_db / 10) * np.exp(-_LN2x4 * (elev / vbw) ** 2)
            self._deposit(echoes, r_ghost, ghost)

    def _deposit(self, echoes: np.ndarray, r: np.ndarray, level: np.ndarray) -> None:
        """Add ``level`` at ranges ``r`` (P, K) into bins, split linearly between the two nearest."""
        n_bins, n = echoes.shape
        f = r / self.dr - 0.5
        i0 = np.floor(f).astype(np.int64)
        w1 = f - i0
        cols = np.broadcast_to(np.arange(n)[:, None], r.shape)
        flat = echoes.reshape(-1)
        for idx, w in ((i0, 1.0 - w1), (i0 + 1, w1)):
            ok = (idx >= 0) & (idx < n_bins)
            flat += np.bincount((idx[ok] * n + cols[ok]), weights=(level * w)[ok], minlength=flat.size)


def _angle_within(a: float, lo: float, hi: float) -> bool:
    """Whether angle ``a`` lies in the (possibly wide) interval ``[lo, hi]`` modulo 2 pi."""
    if hi - lo >= 2 * math.pi:
        return True
    return (a - lo) % (2 * math.pi) <= hi - lo


def structure_targets(structure: Structure, beam_width: float, reference_range: float) -> list[Target]:
    """Walls and piles of ``structure`` as static targets for a beam-forming sensor of ``beam_width`` [rad].

    A wall's scatterers are scaled by the Gaussian beam's equivalent width at the reference
    range, ``1.064 * beam_width * r_ref``, so a wall at normal incidence fills a cell with its
    level at every range (the beam holds more of the wall as range grows as the echo weakens).
    """
    out = []
    if structure.walls is not None:
        w = structure.walls
        scaled = RoughShape(w.name, w.points, w.normals, w.weights / (1.0645 * beam_width * reference_range),
                            w.exponents, w.extent, w.roughness)
        out.append(Target(0, StaticTrajectory(0.0, 0.0), scaled, 0.0))
    if structure.piles is not None:
        out.append(Target(0, StaticTrajectory(0.0, 0.0), structure.piles, 0.0))
    return out

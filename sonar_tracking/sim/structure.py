"""Static structure and receiver artefacts of real sonar images, and the 8-bit output coding.

Real echoes are not only targets and speckle: a tank's walls, a harbour's quay, breakwater and
piles, and the seabed where the vertical beam meets it give bright, extended echoes that do not
move; the transducer rings for the first range bins after each ping; and drivers publish 8-bit
log-compressed counts in which every cell below the gain floor is exactly 0. This module adds
these, as opt-in settings (``structure.*``, ``output.*``), so the front ends can be tested
without real data. With ``structure.kind = none`` and ``output.coding = linear_amplitude`` (the
defaults) nothing here runs and a sector holds only the scene's targets, clutter and noise.

Layouts (world frame, metres):

* ``tank`` (SeaKing at the origin looking +x, the FLS scenes): a back wall at x = 28.5 m across
  y = -8..8 m, and side walls at y = +/-8 m, which cross the +/-45 deg sector along its edges
  (seen from 11 m at the edge beams out to 30 m at +/-15 deg);
* ``harbour`` (the ESC sonar at (-2000, 0)): a quay wall at x = 1150 m (range about 3150 m), a
  rubble breakwater along bearing 21 deg (the sector's left edge) from 1850 to 3250 m, and a
  field of 5 x 3 piles 40 m apart at x = 600..760 m, y = 60..140 m, clear of the paper
  scenarios' target paths.

Echo model. Every level is the mean cell echo relative to the background reverberation or
clutter mean ``1 / lam`` (``lam`` the scene's background rate), in dB:

* walls are rows of scatterers every ``spacing`` metres, jittered across a face of some
  thickness, with exponentially distributed strengths drawn once per scene (a fixed texture); a
  rough face scatters ``roughness + (1 - roughness) |cos(incidence)|`` of its normal-incidence
  echo, so walls seen at grazing incidence stay visible, as rubble and concrete do. Weights are
  scaled so a wall at normal incidence fills a cell with about ``wall_db``;
* piles are isotropic points of ``pile_db`` (one cell each on the harbour sonar);
* the seabed is a band of ranges ``[seabed_range_min, seabed_range_max]`` (in the sensor frame:
  where the vertical beam meets the bottom at constant altitude) of ``seabed_db``, edges soft,
  with a static log-normal texture of ``texture_db`` standard deviation fixed in the world (a
  sum of random plane waves of wavelengths from ``texture_scale`` to 4 ``texture_scale``);
* ringdown is ``ringdown_db`` at the first range bin of the receive window, decaying as
  ``exp(-(r - r_first) / ringdown_length)`` on every beam.

The SeaKing renders walls and piles through its own beam pattern, pulse length and surface
multipath (they are static :class:`~.scene.Target` objects to it); the harbour sonar sums them
into its cells. Static echoes fluctuate from ping to ping much less than speckle: each cell's
mean is multiplied by a unit-mean gamma variate of shape ``steadiness`` (1 would be as speckled
as reverberation), and added to the sector.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.intensity import decode, encode_db
from sonar_tracking.sim.shapes import Shape

__all__ = ['STRUCTURE_KINDS', 'OUTPUT_CODINGS', 'StructureConfig', 'OutputConfig', 'Structure', 'RoughShape',
           'Texture', 'walls_of', 'build_structure', 'encode_output', 'decode_output', 'TANK_WALLS', 'HARBOUR_WALLS',
           'HARBOUR_PILES', 'HARBOUR_SONAR_XY']

STRUCTURE_KINDS = ('none', 'tank', 'harbour')
OUTPUT_CODINGS = ('linear_amplitude', 'db')

#: Tank walls: (start, end) in the world frame; the SeaKing is at the origin looking +x.
TANK_WALLS = (((28.5, -8.0), (28.5, 8.0)), ((-1.0, 8.0), (28.5, 8.0)), ((-1.0, -8.0), (28.5, -8.0)))
#: The ESC paper's sonar position [m]; the harbour layout is laid out around it.
HARBOUR_SONAR_XY = (-2000.0, 0.0)
_BREAKWATER = math.radians(21.0)
#: Harbour walls: the quay and the breakwater along the sector's left edge.
HARBOUR_WALLS = (((1150.0, -100.0), (1150.0, 1000.0)),
                 tuple((HARBOUR_SONAR_XY[0] + r * math.cos(_BREAKWATER),
                        HARBOUR_SONAR_XY[1] + r * math.sin(_BREAKWATER))
                       for r in (1850.0, 3250.0)))
#: Harbour pile field: 5 x 3 piles 40 m apart.
HARBOUR_PILES = tuple((x, y) for x in (600.0, 640.0, 680.0, 720.0, 760.0) for y in (60.0, 100.0, 140.0))
#: Scatterer spacing along a wall and face thickness [m], per layout.
_WALL_SAMPLING = {'tank': (0.1, 0.2), 'harbour': (2.0, 10.0)}


@dataclass(frozen=True)
class StructureConfig(Config):
    """Static structure (walls, piles, seabed band) and transducer ringdown of the simulated scene."""

    kind: str = setting('none', 'static structure: none, tank (back and side walls round the FLS tank) or '
                        'harbour (quay, breakwater, pile field), each with a seabed band and ringdown',
                        choices=STRUCTURE_KINDS, read_only=True)
    wall_db: float = setting(20.0, 'wall echo at normal incidence re the reverberation mean', unit='dB',
                             low=-20.0, high=80.0, read_only=True)
    roughness: float = setting(0.3, 'share of a wall\'s normal-incidence echo it still returns at grazing '
                               'incidence', low=0.0, high=1.0, read_only=True)
    pile_db: float = setting(20.0, 'echo of a pile (harbour) re the reverberation mean', unit='dB', low=-20.0,
                             high=80.0, read_only=True)
    seabed_db: float = setting(8.0, 'seabed band echo re the reverberation mean', unit='dB', low=-20.0, high=80.0,
                               read_only=True)
    seabed_range_min: float = setting(3.0, 'near edge of the seabed band (half level)', unit='m', low=0.0,
                                      high=1e5, read_only=True)
    seabed_range_max: float = setting(6.0, 'far edge of the seabed band (half level)', unit='m', low=0.0,
                                      high=1e5, read_only=True)
    texture_db: float = setting(4.0, 'standard deviation of the seabed\'s static texture', unit='dB', low=0.0,
                                high=20.0, read_only=True)
    texture_scale: float = setting(1.0, 'shortest wavelength of the seabed texture', unit='m', low=1e-3,
                                   high=1e4, read_only=True)
    ringdown_db: float = setting(30.0, 'transducer ringdown at the first range bin re the reverberation mean',
                                 unit='dB', low=-20.0, high=80.0, read_only=True)
    ringdown_length: float = setting(0.2, 'range over which the ringdown falls by 1/e', unit='m', low=1e-3,
                                     high=1e4, read_only=True)
    steadiness: float = setting(8.0, 'gamma shape of the ping-to-ping fluctuation of static echoes '
                                '(1 = as speckled as reverberation)', low=0.5, high=1e4, read_only=True)

    def validate(self) -> None:
        if self.seabed_range_max <= self.seabed_range_min:
            raise ConfigError(f'structure.seabed_range_max = {self.seabed_range_max} m must be beyond '
                              f'structure.seabed_range_min = {self.seabed_range_min} m')


@dataclass(frozen=True)
class OutputConfig(Config):
    """How sector values are published: linear amplitude (float) or 8-bit log-compressed counts."""

    coding: str = setting('linear_amplitude', 'sector values: linear_amplitude (float) or db (8-bit counts of '
                          'a log-compressed amplitude, decoded by intensity coding db)', choices=OUTPUT_CODINGS,
                          read_only=True)
    db_span: float = setting(60.0, 'db coding: the dB range of counts 0..255 (intensity.db_span)', unit='dB',
                             low=1.0, high=200.0, read_only=True)
    gain_floor: float = setting(0.7, 'db coding: amplitude of count 1; weaker echoes are count 0 (no echo)',
                                low=1e-9, high=1e9, read_only=True)


def encode_output(amplitudes: np.ndarray, config: OutputConfig) -> np.ndarray:
    """Sector values as published: float32 amplitudes, or uint8 dB counts (``intensity.encode_db``)."""
    if config.coding == 'db':
        return encode_db(amplitudes, config.db_span, 255, reference=config.gain_floor)
    return amplitudes


def decode_output(values: np.ndarray, config: OutputConfig) -> np.ndarray:
    """Published sector values back to linear amplitude, relative to the counts' reference (``intensity.decode``)."""
    if config.coding == 'db':
        return decode(values, 'db', db_span=config.db_span, full_scale=255.0)
    return values


@dataclass(frozen=True, eq=False)
class RoughShape(Shape):
    """Scatterers of rough faces: ``roughness + (1 - roughness) |cos(incidence)|``; isotropic points 1."""

    roughness: float = 0.3

    def response(self, toward_sonar: np.ndarray) -> np.ndarray:
        cos = np.abs(np.sum(toward_sonar * self.normals, axis=-1))
        iso = np.all(self.normals == 0.0, axis=1)
        return self.weights * np.where(iso, 1.0, self.roughness + (1.0 - self.roughness) * cos)


@dataclass(frozen=True, eq=False)
class Texture:
    """A static log-normal texture in the world: ``10^(std_db * f(x, y) / 10)``, f of unit variance."""

    wavevectors: np.ndarray  # (K, 2) [rad/m]
    phases: np.ndarray       # (K,)
    std_db: float

    @classmethod
    def random(cls, rng: np.random.Generator, std_db: float, scale: float, n: int = 16) -> Texture:
        wavelength = scale * np.exp(rng.uniform(0.0, math.log(4.0), n))
        angle = rng.uniform(0.0, 2 * math.pi, n)
        k = (2 * math.pi / wavelength)[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        return cls(k, rng.uniform(0.0, 2 * math.pi, n), float(std_db))

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Texture factor at world points ``(..., 2)``."""
        if self.std_db == 0.0:
            return np.ones(xy.shape[:-1])
        f = np.cos(xy @ self.wavevectors.T + self.phases).sum(axis=-1) * math.sqrt(2.0 / len(self.phases))
        return np.power(10.0, self.std_db * f / 10.0)


@dataclass(frozen=True, eq=False)
class Structure:
    """The static part of a scene: walls and piles (scatterers), seabed band, ringdown."""

    config: StructureConfig
    walls: RoughShape | None      # weights: level x spacing [m] (normal-incidence level per metre of face)
    piles: RoughShape | None      # weights: level of each pile
    texture: Texture

    def seabed(self, ranges: np.ndarray) -> np.ndarray:
        """Mean seabed level (linear, re the reverberation mean) at ``ranges``: half level at the edges."""
        c = self.config
        centre, half = 0.5 * (c.seabed_range_min + c.seabed_range_max), 0.5 * (c.seabed_range_max - c.seabed_range_min)
        return 10 ** (c.seabed_db / 10) * np.exp(-math.log(2.0) * ((np.asarray(ranges) - centre) / half) ** 4)

    def ringdown(self, ranges: np.ndarray) -> np.ndarray:
        """Mean ringdown level at ``ranges``, counted from the first one (the receive window's start)."""
        c = self.config
        r = np.asarray(ranges)
        return 10 ** (c.ringdown_db / 10) * np.exp(-(r - r[0]) / c.ringdown_length)

    def range_profile(self, ranges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Seabed (to be textured) and ringdown levels at ``ranges``; 0 where below 1e-6 of the peak."""
        seabed, ring = self.seabed(ranges), self.ringdown(ranges)
        seabed[seabed < 1e-6 * seabed.max()] = 0.0
        ring[ring < 1e-6 * ring[0]] = 0.0
        return seabed, ring

    def scatterers(self) -> list[RoughShape]:
        return [s for s in (self.walls, self.piles) if s is not None]

    def fluctuate(self, mean: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """One ping's static echoes: ``mean`` times unit-mean gamma variates of shape ``steadiness``."""
        k = self.config.steadiness
        return mean * rng.gamma(k, 1.0 / k, mean.shape)


def walls_of(segments, level: float, spacing: float, thickness: float, roughness: float, toward: tuple,
           rng: np.random.Generator) -> RoughShape:
    """Scatterers every ``spacing`` along each segment, jittered across ``thickness``, normals toward ``toward``."""
    points, normals, weights = [], [], []
    for a, b in segments:
        a, b = np.asarray(a, float), np.asarray(b, float)
        length = float(np.hypot(*(b - a)))
        n = max(2, int(round(length / spacing)))
        u = (b - a) / length
        normal = np.array([-u[1], u[0]])
        if normal @ (np.asarray(toward) - a) < 0:
            normal = -normal
        s = (np.arange(n) + rng.uniform(0.0, 1.0, n)) / n
        across = rng.uniform(-0.5, 0.5, n) * thickness
        points.append(a + s[:, None] * (b - a) + across[:, None] * normal)
        normals.append(np.broadcast_to(normal, (n, 2)))
        weights.append(level * (length / n) * rng.standard_exponential(n))
    pts = np.concatenate(points)
    extent = float(np.hypot(*(pts.max(axis=0) - pts.min(axis=0))))
    return RoughShape('walls', pts, np.concatenate(normals), np.concatenate(weights), np.ones(len(pts)), extent,
                      roughness)


def build_structure(config: StructureConfig, rng: np.random.Generator) -> Structure | None:
    """The structure of ``config.kind`` (None for ``none``); ``rng`` fixes its texture and scatterers."""
    if config.kind == 'none':
        return None
    spacing, thickness = _WALL_SAMPLING[config.kind]
    if config.kind == 'tank':
        segments, sonar, piles = TANK_WALLS, (0.0, 0.0), ()
    else:
        segments, sonar, piles = HARBOUR_WALLS, HARBOUR_SONAR_XY, HARBOUR_PILES
    walls = walls_of(segments, 10 ** (config.wall_db / 10), spacing, thickness, config.roughness, sonar, rng)
    pile_shape = None
    if piles:
        p = np.asarray(piles, float)
        pile_shape = RoughShape('piles', p, np.zeros_like(p), np.full(len(p), 10 ** (config.pile_db / 10)),
                                np.ones(len(p)), float(np.hypot(*(p.max(axis=0) - p.min(axis=0)))))
    texture = Texture.random(rng, config.texture_db, config.texture_scale)
    return Structure(config, walls, pile_shape, texture)

"""Multibeam imaging sonar (Oculus M-series, Tritech Gemini, ARIS/DIDSON class): every beam formed at once.

One frame every ``1 / frame_rate`` seconds is one sector (``ping_period`` 0, ``scan_time`` the frame
period, ``end_of_sweep`` True): rows are ``n_bins`` range bins between ``range_min`` and ``range_max``
(row 0 nearest), columns ``n_beams`` beams evenly spaced over ``fov_deg`` in increasing bearing. A cell's
value is the linear echo amplitude ``|F|`` (float32, the square root of the intensity modelled below);
``output.coding = db`` of the simulator turns it into 8-bit log-compressed counts as the drivers send.

Model of the complex field of cell (bin i at range r_i, beam j at bearing theta_j)::

    F_ij = lam^(-1/2) [ sqrt(L(r_i) tau_ij S_ij) Z_ij + E_ij ] + sqrt(N(r_i)) n_ij,      value = |F_ij|

* **Speckle, exact law.** ``W`` is a field of independent unit complex Gaussians ``CN(0, 1)`` (bins x
  beams). The beamformed speckle is the 2-D circular convolution ``Z = W (*) (h_p h_b^T)``: ``h_b`` the
  array's amplitude response sampled at the beam spacing and truncated to +-``pattern_extent`` beam widths,
  ``h_p`` the pulse response sampled at the bin spacing, each normalised to ``sum |h|^2 = 1``. Every
  ``Z_ij`` is then exactly ``CN(0, 1)``: ``|Z|^2`` is unit-mean exponential (Rayleigh amplitude), and
  ``E[Z_ij Z*_kl] = (h_p * h_p)(i - k) (h_b * h_b)(j - l)``: neighbouring beams are as correlated as the
  beam pattern's overlap says (about 4 beams per beam width on an Oculus, strongly correlated). FFTs,
  complex64. The circular wrap makes the first and last beams (bins) neighbours of each other, which
  changes no cell's law.
* **Beam pattern.** ``h_b(delta) = H(s) / H(0)`` with ``H(s) = sum_n w_n cos(2 pi s x_n)`` the response of
  a 64-element line aperture ``x_n`` in ``[-1/2, 1/2]``: uniform weights (first sidelobe -13.26 dB) when
  ``sidelobe_db >= -13.26``, else Taylor weights with peak sidelobe ``sidelobe_db``. ``s = s_3 2 delta /
  theta_3`` with ``H(s_3)^2 = 1/2``, so the -3 dB width is ``beam_width_deg`` (``theta_3``); zero beyond
  ``pattern_extent theta_3``. The pattern depends on the bearing offset only (the widening ``1 / cos`` of
  an electronically steered beam far off broadside is left out), which keeps the convolution
  shift-invariant.
* **Pulse.** ``h_p(x) = exp(-2 ln 2 (x / w_r)^2)``, ``x`` the range offset, ``w_r = sqrt(pulse_length^2 +
  bin^2)`` the range resolution (half-power width): a bin integrates at least its own depth.
* **K-distributed clutter.** ``tau = 1`` (``clutter = rayleigh``), or ``tau ~ Gamma(nu, 1 / nu)`` (unit
  mean, ``nu = k_shape``) constant over blocks of ``texture_bins x texture_beams`` cells, the texture's
  correlation length. Given ``tau`` the intensity is exponential of mean ``tau``, so ``I / L`` is K with
  shape ``nu``: ``P(I / L > x) = 2 (nu x)^(nu/2) K_nu(2 sqrt(nu x)) / Gamma(nu)`` (:func:`k_sf`).
* **Frozen speckle that decorrelates with motion.** ``W`` and ``tau`` persist from frame to frame. Each
  frame, the world point every cell looked at in the last frame is put in the sensor's new pose; its
  displacement in resolution cells is ``d = sqrt((dr / w_r)^2 + (dtheta / theta_3)^2)``, and::

      W <- rho W + sqrt(1 - rho^2) xi,      rho = exp(-(d / d0)^2),      xi ~ CN(0, 1) fresh

  (``d0 = decorrelation_cells``), which keeps ``W`` ``CN(0, 1)``; with one ``rho`` over the frame, ``Z``
  correlates with the last frame's by ``rho`` and ``|Z|^2`` by ``rho^2``. Each texture block keeps its
  ``tau`` with probability ``rho`` at its centre, else draws a new one (the gamma marginal stays). A
  platform that has not moved leaves ``W`` and ``tau`` as they are: the speckle of a static scene is
  identical frame to frame (the values too, with ``receiver_noise`` off).
* **Mean level (range-dependent gain)**, intensity re amplitude 1::

      L(r) = 10^(background_db / 10) (r / r_ref)^(residual / 10) [1 + 10^(seabed_db / 10) G(r)]
      G(r) = exp(-4 ln 2 ((asin(a / r) - tilt) / vbw)^2)  for r > a, else 0

  volume reverberation plus the seabed seen through the vertical beam (sonar ``altitude`` a above the
  bottom, axis tilted down by ``tilt_deg``, vertical -3 dB width ``vbw``): half its level at the grazing
  range ``r_g = a / sin(tilt + vbw / 2)``, a soft edge, full where the beam axis meets the bottom. The
  time-varying gain does not quite undo spreading: ``residual_db_per_decade`` is what is left.
* **Receiver noise**, fresh each frame: ``n ~ CN(0, 1)``, ``N(r) = 10^((background_db + noise_db) / 10)
  (r / r_ref)^(tvg / 10)``: it grows with the gain. Alone it has exponential intensity.
* **Targets and structure.** Each scatterer k (range ``r_k``, bearing ``theta_k``) adds::

      E_ij += a_k exp(i phi_k) h_b(theta_j - theta_k) h_p(r_i - r_k),     a_k^2 = SNR g_k L(r_k)

  ``g_k`` the shape's aspect response (:meth:`~.shapes.Shape.response`: a shape's best aspect sums to 1),
  so a point target's echo at the cell on it is ``SNR`` (``Target.snr_db``) times the background level at
  its range; an extended target shares it among its scatterers, and its echo spreads across beams exactly
  as the beam pattern says, sidelobes included. ``phi_k = 4 pi r_k / lambda`` (the two-way path): fixed
  while the scatterer and the sonar stay put (static structure is frozen), effectively fresh each frame
  once either moves by a wavelength (a fluctuating echo). Structure (``scene.structure``: walls and piles)
  carries its level re the background in its weights: a facet scatterer of a wall carries ``level x
  spacing`` and is divided by ``r_k B``, ``B = integral h_b^2`` the beam's equivalent width, so a wall at
  normal incidence fills its cells with its level; an isotropic point (a pile) carries its level.
* **Acoustic shadows.** With ``g = 10^(shadow_db / 10)``: behind every structure scatterer, in its beam
  and the beams either side, to the last bin, ``S = g`` (walls and piles stand higher than the sonar and
  fill the vertical beam). Behind a target of ``Shape.height`` h > 0, in the beams it spans, from its far
  side over ``r h / (a - h)`` (the shadow on the bottom of an object h high under a sonar at altitude a;
  to the last bin when ``h >= a``), only the seabed part of the background is shadowed:
  ``S = (L_w + g L_s) / L`` with ``L_w``, ``L_s`` the water-column and seabed parts of ``L`` (a diver
  blocks a sliver of the vertical beam's volume, but hides the bottom behind it). Echoes themselves are
  not shadowed.

``lam`` is the scene's clutter rate (``Scene.lam_at``): it scales clutter and echoes together (a gain),
as the ESC amplitude law's ``1 / lam`` mean does; receiver noise does not depend on it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from scipy.signal.windows import taylor
from scipy.special import gamma as gamma_fn
from scipy.special import kv

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.fan import fan_extent
from sonar_tracking.core.sector import MAX_CELLS, SectorGeometry
from sonar_tracking.sim.scene import Scene, Target
from sonar_tracking.sim.sensor import Pose, SimSector

__all__ = ['ImagingConfig', 'ImagingSonar', 'BeamPattern', 'CLUTTER_LAWS', 'UNIFORM_SIDELOBE_DB', 'k_sf',
           'complex_normal']

CLUTTER_LAWS = ('rayleigh', 'k')
#: First sidelobe of an unshaded line aperture (sinc) [dB].
UNIFORM_SIDELOBE_DB = -13.26
_LN2 = math.log(2.0)
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class ImagingConfig(Config):
    """Imaging-sonar head, beam pattern, levels, clutter law and frame rate."""

    n_beams: int = setting(512, 'beams formed at once, evenly spaced over fov_deg', low=1, high=4096, read_only=True)
    fov_deg: float = setting(130.0, 'horizontal field of view, edge to edge of the beams', unit='deg', low=0.1,
                             high=180.0, read_only=True)
    beam_width_deg: float = setting(1.0, 'horizontal -3 dB beam width (angular resolution)', unit='deg', low=0.01,
                                    high=30.0, read_only=True)
    sidelobe_db: float = setting(UNIFORM_SIDELOBE_DB, 'peak sidelobe of the beam pattern re its main lobe: -13.26 '
                                 'or above is an unshaded aperture (sinc), below a Taylor-shaded one', unit='dB',
                                 low=-60.0, high=-10.0, read_only=True)
    pattern_extent: float = setting(8.0, 'half-width of the beam pattern kept; sidelobes beyond are dropped',
                                    unit='beam widths', low=1.0, high=64.0, read_only=True)
    vertical_beam_width_deg: float = setting(20.0, 'vertical -3 dB beam width', unit='deg', low=0.5, high=90.0,
                                             read_only=True)
    frequency_khz: float = setting(750.0, 'centre frequency (the wavelength of echo phases)', unit='kHz', low=10.0,
                                   high=5000.0, read_only=True)
    range_min: float = setting(0.1, 'near edge of the first range bin', unit='m', low=0.0, high=1000.0,
                               read_only=True)
    range_max: float = setting(30.0, 'far edge of the last range bin (the range setting)', unit='m', low=0.1,
                               high=1000.0, read_only=True)
    n_bins: int = setting(1000, 'range bins per beam', low=2, high=16384, read_only=True)
    pulse_length: float = setting(0.004, 'range resolution of the (compressed) pulse, c tau / 2', unit='m', low=0.0,
                                  high=10.0, read_only=True)
    frame_rate: float = setting(20.0, 'frames per second; at most c / (2 range_max)', unit='Hz', low=0.1,
                                high=100.0, read_only=True)
    sound_speed: float = setting(1500.0, 'speed of sound', unit='m/s', low=1300.0, high=1700.0, read_only=True)
    altitude: float = setting(3.0, 'height of the sonar above the seabed', unit='m', low=0.05, high=1000.0,
                              read_only=True)
    tilt_deg: float = setting(10.0, 'downward tilt of the acoustic axis', unit='deg', low=-45.0, high=90.0,
                              read_only=True)
    background_db: float = setting(0.0, 'water-column (volume reverberation) mean intensity at the reference '
                                   'range, re amplitude 1', unit='dB', low=-80.0, high=80.0, read_only=True)
    seabed_db: float = setting(10.0, 'seabed backscatter on the vertical beam axis re the water column', unit='dB',
                               low=-80.0, high=60.0, read_only=True)
    reference_range: float = setting(10.0, 'range at which background_db and noise_db are given', unit='m',
                                     low=0.01, high=1000.0, read_only=True)
    residual_db_per_decade: float = setting(-5.0, 'slope of the background over range that the time-varying '
                                            'gain leaves (spreading minus gain)', unit='dB/decade', low=-40.0,
                                            high=40.0, read_only=True)
    tvg_db_per_decade: float = setting(20.0, 'time-varying gain: receiver noise grows with range by it',
                                       unit='dB/decade', low=0.0, high=60.0, read_only=True)
    noise_db: float = setting(-20.0, 'receiver noise at the reference range re the water column there', unit='dB',
                              low=-100.0, high=40.0, read_only=True)
    receiver_noise: bool = setting(True, 'add receiver noise, fresh each frame (off: a static scene gives '
                                   'identical frames)', read_only=True)
    clutter: str = setting('rayleigh', 'clutter law: rayleigh (exponential intensity) or k (gamma texture times '
                           'speckle)', choices=CLUTTER_LAWS, read_only=True)
    k_shape: float = setting(0.5, 'K-distribution shape nu (small: heavy tail; large: close to Rayleigh)', low=0.05,
                             high=100.0, read_only=True)
    texture_bins: int = setting(32, 'range bins of a K texture block (its correlation length in range)', low=1,
                                high=16384, read_only=True)
    texture_beams: int = setting(16, 'beams of a K texture block (its correlation length across beams)', low=1,
                                 high=4096, read_only=True)
    decorrelation_cells: float = setting(1.0, 'd0: displacement, in resolution cells, that leaves speckle '
                                         'correlated by 1/e', unit='cells', low=0.01, high=1000.0, read_only=True)
    shadow_db: float = setting(-15.0, 'background behind an object re its level without it', unit='dB', low=-80.0,
                               high=0.0, read_only=True)

    def validate(self) -> None:
        if self.range_max <= self.range_min:
            raise ConfigError(f'imaging.range_max = {self.range_max} m must be beyond imaging.range_min = '
                              f'{self.range_min} m')
        if self.n_bins * self.n_beams > MAX_CELLS:
            raise ConfigError(f'imaging.n_bins x imaging.n_beams = {self.n_bins * self.n_beams} cells is more than '
                              f'{MAX_CELLS}')
        limit = self.sound_speed / (2.0 * self.range_max)
        if self.frame_rate > limit * (1.0 + 1e-9):
            raise ConfigError(f'imaging.frame_rate = {self.frame_rate:g} Hz: an echo from imaging.range_max = '
                              f'{self.range_max:g} m returns after {1e3 / limit:.1f} ms, so at most {limit:.3g} Hz')

    @property
    def frame_period(self) -> float:
        """Time between frames [s]."""
        return 1.0 / self.frame_rate

    @property
    def bin_size(self) -> float:
        """Depth of a range bin [m]."""
        return (self.range_max - self.range_min) / self.n_bins

    @property
    def beam_width(self) -> float:
        """Horizontal -3 dB beam width [rad]."""
        return math.radians(self.beam_width_deg)

    @property
    def range_resolution(self) -> float:
        """Half-power width of the pulse response, ``sqrt(pulse_length^2 + bin^2)`` [m]."""
        return math.hypot(self.pulse_length, self.bin_size)

    @property
    def wavelength(self) -> float:
        """Acoustic wavelength [m]."""
        return self.sound_speed / (self.frequency_khz * 1e3)

    @property
    def grazing_range(self) -> float:
        """Range where the lower edge of the vertical beam meets the seabed [m] (inf if it never does)."""
        angle = math.radians(self.tilt_deg + 0.5 * self.vertical_beam_width_deg)
        return self.altitude / math.sin(angle) if angle > 0 else math.inf

    def geometry(self) -> SectorGeometry:
        """The fixed cell grid of every frame."""
        inc = math.radians(self.fov_deg) / self.n_beams
        dr = self.bin_size
        return SectorGeometry(angle_min=-0.5 * math.radians(self.fov_deg) + 0.5 * inc, angle_increment=inc,
                              n_beams=self.n_beams, range_min=self.range_min + 0.5 * dr,
                              range_max=self.range_max - 0.5 * dr, n_bins=self.n_bins, ping_period=0.0,
                              scan_time=self.frame_period)


class BeamPattern:
    """Real amplitude response of a receive beam against the bearing offset [rad]: 1 on the axis, -3 dB
    at +-``beam_width / 2``, 0 beyond +-``extent`` beam widths (see the module's model)."""

    N_ELEMENTS = 64

    def __init__(self, beam_width: float, sidelobe_db: float = UNIFORM_SIDELOBE_DB, extent: float = 8.0,
                 n_table: int = 16384) -> None:
        m = self.N_ELEMENTS
        if sidelobe_db >= UNIFORM_SIDELOBE_DB:
            w = np.ones(m)
        else:
            a = math.acosh(10 ** (-sidelobe_db / 20)) / math.pi
            nbar = max(3, math.ceil(2 * a * a + 0.5))  # the smallest nbar with monotonic Taylor weights
            w = taylor(m, nbar=nbar, sll=-sidelobe_db, norm=False)
        x = (np.arange(m) + 0.5) / m - 0.5
        w = w / w.sum()

        def aperture(s: np.ndarray) -> np.ndarray:
            return np.cos(_TWO_PI * s[:, None] * x[None, :]) @ w

        s = np.linspace(0.0, 2.0, 20001)
        h2 = aperture(s) ** 2
        k = int(np.argmax(h2 <= 0.5))
        s3 = float(np.interp(0.5, [h2[k], h2[k - 1]], [s[k], s[k - 1]]))
        self.beam_width = float(beam_width)
        self.half_width = float(extent) * self.beam_width
        self._delta = np.linspace(0.0, self.half_width, n_table)
        self._table = aperture(2.0 * s3 * self._delta / self.beam_width)

    def __call__(self, delta: np.ndarray | float) -> np.ndarray:
        """Amplitude response at bearing offsets ``delta`` [rad] (any shape)."""
        return np.interp(np.abs(delta), self._delta, self._table, right=0.0)

    @property
    def equivalent_width(self) -> float:
        """``integral h^2 d delta`` [rad]: the width of a rectangular beam of the same power."""
        h2 = self._table ** 2
        return float(2.0 * np.sum(0.5 * (h2[1:] + h2[:-1]) * np.diff(self._delta)))


def k_sf(x: np.ndarray, nu: float) -> np.ndarray:
    """Survival function ``P(I > x)`` of unit-mean K-distributed intensity of shape ``nu``."""
    x = np.asarray(x, dtype=float)
    z = 2.0 * np.sqrt(nu * np.maximum(x, 1e-300))
    return np.where(x > 0, 2.0 * (nu * x) ** (nu / 2) * kv(nu, z) / gamma_fn(nu), 1.0)


def complex_normal(rng: np.random.Generator, shape: tuple[int, ...], scale: np.ndarray | None = None) -> np.ndarray:
    """Independent ``CN(0, 1)`` samples (complex64): real and imaginary parts of variance 1/2; times
    ``scale`` (real, broadcast to ``shape``) if given."""
    pair = rng.standard_normal(shape + (2,), dtype=np.float32)
    factor = np.float32(math.sqrt(0.5)) if scale is None else np.float32(math.sqrt(0.5)) * scale
    pair *= np.asarray(factor, dtype=np.float32)[..., None]
    return pair.view(np.complex64)[..., 0]


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % _TWO_PI - math.pi


class ImagingSonar:
    """One whole frame per ``frame_period``, starting at ``t = frame_period``; the speckle field, the clutter
    texture and the last pose persist between frames (see the module's model)."""

    def __init__(self, config: ImagingConfig) -> None:
        c = self.config = config
        g = self.geometry = config.geometry()
        self.ranges = g.ranges()
        self.bearings = g.bearings()
        self.pattern = BeamPattern(c.beam_width, c.sidelobe_db, c.pattern_extent)
        inc, dr = g.angle_increment, c.bin_size
        self.beam_half_taps = min(int(math.floor(self.pattern.half_width / inc + 1e-9)), (c.n_beams - 1) // 2)
        self.bin_width = c.range_resolution / dr  # half-power width of h_p in bins
        self.bin_half_taps = min(int(math.ceil(2.0 * self.bin_width)), (c.n_bins - 1) // 2)
        kb = self.pattern(np.arange(-self.beam_half_taps, self.beam_half_taps + 1) * inc)
        kp = self._pulse(np.arange(-self.bin_half_taps, self.bin_half_taps + 1, dtype=float))
        #: The speckle kernels, each with sum |h|^2 = 1.
        self.beam_kernel = kb / np.sqrt(np.sum(kb ** 2))
        self.pulse_kernel = kp / np.sqrt(np.sum(kp ** 2))
        kernel = np.zeros(g.shape, dtype=np.complex64)
        rows = np.arange(-self.bin_half_taps, self.bin_half_taps + 1) % c.n_bins
        cols = np.arange(-self.beam_half_taps, self.beam_half_taps + 1) % c.n_beams
        kernel[np.ix_(rows, cols)] = np.outer(self.pulse_kernel, self.beam_kernel)
        self._kernel_spectrum = sfft.fft2(kernel).astype(np.complex64)
        rel = self.ranges / c.reference_range
        self.seabed_gain = self._seabed_gain(self.ranges)
        #: Background (clutter) mean intensity per bin at lam 1: water column plus seabed, after the TVG.
        self.level = self.level_at(self.ranges)
        #: Receiver noise mean intensity per bin.
        self.noise_level = 10 ** ((c.background_db + c.noise_db) / 10) * rel ** (c.tvg_db_per_decade / 10)
        self._sqrt_level = np.sqrt(self.level).astype(np.float32)[:, None]
        self._sqrt_noise = np.sqrt(self.noise_level).astype(np.float32)[:, None]
        shadow = 10 ** (c.shadow_db / 10)
        self._shadow_amp = np.float32(math.sqrt(shadow))
        water = self.level / (1.0 + 10 ** (c.seabed_db / 10) * self.seabed_gain)
        self._seabed_shadow_amp = np.sqrt((water + shadow * (self.level - water)) / self.level).astype(np.float32)
        self._block_shape = (-(-c.n_bins // c.texture_bins), -(-c.n_beams // c.texture_beams))
        centre_rows = np.minimum(np.arange(self._block_shape[0]) * c.texture_bins + c.texture_bins // 2, c.n_bins - 1)
        centre_cols = np.minimum(np.arange(self._block_shape[1]) * c.texture_beams + c.texture_beams // 2,
                                 c.n_beams - 1)
        self._block_centres = np.ix_(centre_rows, centre_cols)
        # Cell grid for the motion rule (float32: the displacements are small differences of ranges).
        self._r32 = self.ranges.astype(np.float32)[:, None]
        self.clutter, self.k_shape = c.clutter, c.k_shape
        self.reset()

    def reset(self) -> None:
        """Back to the first frame; the speckle and texture are drawn anew at the next frame."""
        self.frame = 0
        self._w: np.ndarray | None = None
        self._z: np.ndarray | None = None
        self._tau: np.ndarray | None = None
        self._background: np.ndarray | None = None
        self._pose: Pose | None = None
        self._lam_cache: tuple[tuple, np.ndarray | float] | None = None
        self._structure_cache: tuple[tuple, np.ndarray, np.ndarray | None] | None = None

    @property
    def next_time(self) -> float:
        """Time of the next frame [s]."""
        return (self.frame + 1) * self.config.frame_period

    def coverage(self) -> tuple[float, float, float, float]:
        """Sensor-frame bounding box ``(x_min, x_max, y_min, y_max)`` of the fan."""
        return fan_extent(self.geometry)

    def set_clutter(self, clutter: str, k_shape: float | None = None) -> None:
        """Change the clutter law (``rayleigh`` or ``k``, and the K shape) from the next frame on; a new
        texture is drawn then."""
        if clutter not in CLUTTER_LAWS:
            raise ConfigError(f'clutter = {clutter!r} is not one of {list(CLUTTER_LAWS)}')
        k_shape = self.k_shape if k_shape is None else float(k_shape)
        if not 0.05 <= k_shape <= 100.0:
            raise ConfigError(f'k_shape = {k_shape} must be in [0.05, 100]')
        if (clutter, k_shape) != (self.clutter, self.k_shape):
            self.clutter, self.k_shape = clutter, k_shape
            self._tau, self._background = None, None

    # -- levels ------------------------------------------------------------------------------------

    def _pulse(self, offset_bins: np.ndarray) -> np.ndarray:
        return np.exp(-2.0 * _LN2 * (offset_bins / self.bin_width) ** 2)

    def _seabed_gain(self, r: np.ndarray) -> np.ndarray:
        c = self.config
        r = np.asarray(r, dtype=float)
        elevation = np.arcsin(np.clip(c.altitude / np.maximum(r, 1e-9), 0.0, 1.0))
        off = (elevation - math.radians(c.tilt_deg)) / math.radians(c.vertical_beam_width_deg)
        return np.where(r > c.altitude, np.exp(-4.0 * _LN2 * off * off), 0.0)

    def level_at(self, r: np.ndarray) -> np.ndarray:
        """Background mean intensity at ranges ``r`` [m] (lam 1, no shadow): water column plus seabed."""
        c = self.config
        r = np.asarray(r, dtype=float)
        water = 10 ** (c.background_db / 10) * (np.maximum(r, 1e-6) / c.reference_range) ** (
            c.residual_db_per_decade / 10)
        return water * (1.0 + 10 ** (c.seabed_db / 10) * self._seabed_gain(r))

    def speckle_correlation(self, cells: float | np.ndarray) -> float | np.ndarray:
        """The model's ``rho`` for a displacement of ``cells`` resolution cells."""
        return np.exp(-(np.asarray(cells) / self.config.decorrelation_cells) ** 2)

    # -- frames ------------------------------------------------------------------------------------

    def next_sector(self, scene: Scene, rng: np.random.Generator) -> SimSector:
        """Simulate the next frame of ``scene``; ``rng`` draws the speckle, texture and noise."""
        t = self.next_time
        self.frame += 1
        x, y, yaw, _, _ = scene.platform_pose(t)
        pose = (x, y, yaw)
        self._evolve(pose, rng)
        assert self._z is not None and self._background is not None
        echoes, shadow = self._render(scene, t, pose)
        background = self._background if shadow is None else self._background * shadow
        field = background * self._z
        if echoes is not None:
            field += echoes
        lam = self._lam(scene, pose)
        if not (isinstance(lam, float) and lam == 1.0):
            field *= np.asarray(1.0 / np.sqrt(lam), dtype=np.float32)
        if self.config.receiver_noise:
            field += complex_normal(rng, self.geometry.shape, self._sqrt_noise)
        return SimSector(stamp=t, amplitudes=np.abs(field), geometry=self.geometry, pose=pose, end_of_sweep=True)

    def _evolve(self, pose: Pose, rng: np.random.Generator) -> None:
        """Bring the speckle field ``W``, its beamformed ``Z`` and the texture to ``pose``."""
        shape = self.geometry.shape
        rho = None
        if self._w is None:
            self._w = complex_normal(rng, shape)
            self._z = None
        elif pose != self._pose:
            assert self._pose is not None
            rho = self.motion_correlation(self._pose, pose)
            xi = complex_normal(rng, shape, np.sqrt(np.maximum(1.0 - rho * rho, 0.0)))
            xi += self._w * rho
            self._w = xi
            self._z = None
        self._pose = pose
        if self.clutter == 'k':
            n_blocks = self._block_shape
            if self._tau is None:
                self._tau = rng.gamma(self.k_shape, 1.0 / self.k_shape, n_blocks)
                self._background = None
            elif rho is not None:
                keep = rng.random(n_blocks) < rho[self._block_centres]
                fresh = rng.gamma(self.k_shape, 1.0 / self.k_shape, n_blocks)
                self._tau = np.where(keep, self._tau, fresh)
                self._background = None
        else:
            self._tau = None
        if self._background is None:
            if self._tau is None:
                self._background = self._sqrt_level
            else:
                c = self.config
                cells = np.repeat(np.repeat(np.sqrt(self._tau), c.texture_bins, 0), c.texture_beams, 1)
                self._background = (self._sqrt_level * cells[:c.n_bins, :c.n_beams]).astype(np.float32)
        if self._z is None:
            spectrum = sfft.fft2(self._w)
            spectrum *= self._kernel_spectrum
            self._z = sfft.ifft2(spectrum, overwrite_x=True).astype(np.complex64, copy=False)

    def motion_correlation(self, old: Pose, new: Pose) -> np.ndarray:
        """``rho`` of every cell (bins x beams, float32) for a sensor moving from pose ``old`` to ``new``:
        where the world point each cell saw from ``old`` lies as seen from ``new``, in resolution cells."""
        c = self.config
        ca, sa = math.cos(new[2]), math.sin(new[2])
        dx, dy = old[0] - new[0], old[1] - new[1]
        ox, oy = ca * dx + sa * dy, -sa * dx + ca * dy  # the old origin in the new frame
        turn = float(_wrap(np.array(old[2] - new[2])))
        a = self.bearings + turn                          # each beam's old direction in the new frame
        along = (ox * np.cos(a) + oy * np.sin(a)).astype(np.float32)[None, :]
        across = (-ox * np.sin(a) + oy * np.cos(a)).astype(np.float32)[None, :]
        # The point r u(a) of the old frame is o + r u(a) in the new one: range |.|, bearing a + delta.
        forward = self._r32 + along
        d_range = (np.hypot(forward, across) - self._r32) / np.float32(c.range_resolution)
        d_bearing = (np.arctan2(across, forward) + np.float32(turn)) / np.float32(c.beam_width)
        d2 = d_range * d_range + d_bearing * d_bearing
        d2 *= np.float32(-1.0 / c.decorrelation_cells ** 2)
        return np.exp(d2)

    def _lam(self, scene: Scene, pose: Pose) -> np.ndarray | float:
        if not scene.regions:
            return float(scene.lam)
        key = (id(scene), scene.lam, len(scene.regions), pose)
        if self._lam_cache is None or self._lam_cache[0] != key:
            r, b = self.ranges[:, None], self.bearings[None, :] + pose[2]
            cells = np.stack([pose[0] + r * np.cos(b), pose[1] + r * np.sin(b)], axis=-1)
            self._lam_cache = (key, np.asarray(scene.lam_at(cells), dtype=np.float32))
        return self._lam_cache[1]

    # -- echoes and shadows ------------------------------------------------------------------------

    def echo_field(self, scene: Scene, t: float, targets: list[Target] | None = None,
                   structure: bool = True) -> np.ndarray:
        """Complex echo field ``E`` (bins x beams, complex64, lam 1) of ``targets`` (default: the scene's)
        and, with ``structure``, of the scene's static structure, at time ``t``: what a frame adds to
        the speckle (``|E|^2 / level`` is a cell's echo-to-background ratio)."""
        x, y, yaw, _, _ = scene.platform_pose(t)
        field = np.zeros(self.geometry.shape, dtype=np.complex64)
        if structure and scene.structure is not None:
            field += self._structure(scene, (x, y, yaw))[0]
        flat = field.reshape(-1)
        for target in scene.targets if targets is None else targets:
            hit = self._target_scatterers(target, t, (x, y, yaw))
            if hit is not None:
                self._deposit(flat, *hit[:3])
        return field

    def _render(self, scene: Scene, t: float, pose: Pose) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Echo field of the targets and structure, and the shadow factor on the background amplitude."""
        field: np.ndarray | None = None
        shadow_from: np.ndarray | None = None  # per beam: range beyond which structure shadows it
        if scene.structure is not None:
            structure_field, shadow_from = self._structure(scene, pose)
            field = structure_field.copy()
        shadow: np.ndarray | None = None
        if shadow_from is not None:
            shadow = np.where(self.ranges[:, None] > shadow_from[None, :], self._shadow_amp, np.float32(1.0))
        for target in scene.targets:
            hit = self._target_scatterers(target, t, pose)
            if hit is None:
                continue
            r, theta, amp = hit
            if field is None:
                field = np.zeros(self.geometry.shape, dtype=np.complex64)
            self._deposit(field.reshape(-1), r, theta, amp)
            block = self._target_shadow(target, r, theta)
            if block is not None:
                if shadow is None:
                    shadow = np.ones(self.geometry.shape, dtype=np.float32)
                rows, cols = block
                shadow[rows, cols] = np.minimum(shadow[rows, cols], self._seabed_shadow_amp[rows, None])
        return field, shadow

    def _target_scatterers(self, target: Target, t: float,
                           pose: Pose) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Range, bearing and complex amplitude of a target's scatterers at ``t`` (None if out of view)."""
        c, g = self.config, self.geometry
        state = target.trajectory.state(t)
        heading = target.trajectory.heading(t)
        dx0, dy0 = state[0] - pose[0], state[1] - pose[1]
        reach = target.shape.extent + c.range_resolution
        r0 = math.hypot(dx0, dy0)
        if r0 - reach > c.range_max or r0 + reach < c.range_min:
            return None
        ch, sh = math.cos(heading), math.sin(heading)
        body = target.shape.points @ np.array([[ch, sh], [-sh, ch]])  # rotate body -> world
        d = body + np.array([dx0, dy0])
        r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-6)
        theta = _wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[2])
        half = 0.5 * (g.angle_max - g.angle_min) + g.angle_increment + self.pattern.half_width
        if not np.any(np.abs(theta - 0.5 * (g.angle_max + g.angle_min)) <= half):
            return None
        toward = -d / r[:, None]
        toward_body = np.stack([toward[:, 0] * ch + toward[:, 1] * sh, -toward[:, 0] * sh + toward[:, 1] * ch], axis=-1)
        gain = target.shape.response(toward_body)
        strength = 10 ** (target.snr_db / 10) * gain * self.level_at(r)
        return r, theta, self._with_phase(np.sqrt(strength), r)

    def _with_phase(self, amplitude: np.ndarray, r: np.ndarray) -> np.ndarray:
        phase = np.mod(4.0 * math.pi * r / self.config.wavelength, _TWO_PI)
        return amplitude * np.exp(1j * phase)

    def _target_shadow(self, target: Target, r: np.ndarray, theta: np.ndarray) -> tuple[slice, slice] | None:
        """Rows and columns of the shadow a target casts (None if it casts none or lies out of the fan)."""
        c, g = self.config, self.geometry
        h = target.shape.height
        if h <= 0.0:
            return None
        j_lo = int(math.floor((theta.min() - g.angle_min) / g.angle_increment + 0.5))
        j_hi = int(math.floor((theta.max() - g.angle_min) / g.angle_increment + 0.5))
        j_lo, j_hi = max(j_lo, 0), min(j_hi, c.n_beams - 1)
        if j_hi < j_lo:
            return None
        near, far = float(r.min()), float(r.max())
        end = far + near * h / (c.altitude - h) if h < c.altitude else math.inf
        i_lo = int(np.searchsorted(self.ranges, far))
        i_hi = int(np.searchsorted(self.ranges, end, side='right'))
        if i_hi <= i_lo:
            return None
        return slice(i_lo, i_hi), slice(j_lo, j_hi + 1)

    def _structure(self, scene: Scene, pose: Pose) -> tuple[np.ndarray, np.ndarray | None]:
        """Echo field of the static structure and, per beam, the range beyond which it shadows the
        background (inf: no shadow); cached while the sonar and the structure stay put."""
        st = scene.structure
        key = (id(st), pose)
        if self._structure_cache is not None and self._structure_cache[0] == key:
            return self._structure_cache[1], self._structure_cache[2]
        assert st is not None
        g = self.geometry
        field = np.zeros(g.shape, dtype=np.complex64)
        shadow_from = np.full(g.n_beams, np.inf)
        for part in st.scatterers():
            d = part.points - np.array(pose[:2])
            r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-6)
            theta = _wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[2])
            level = part.response(-d / r[:, None])
            extended = ~np.all(part.normals == 0.0, axis=1)
            level = np.where(extended, level / (r * self.pattern.equivalent_width), level)
            self._deposit(field.reshape(-1), r, theta, self._with_phase(np.sqrt(level * self.level_at(r)), r))
            # Its beam and the beams either side: scatterers a beam apart leave no gap in a wall's shadow.
            j = np.floor((theta - g.angle_min) / g.angle_increment + 0.5).astype(np.int64)[:, None] + np.arange(-1, 2)
            rr = np.broadcast_to(r[:, None], j.shape)
            inside = (j >= 0) & (j < g.n_beams) & (rr <= self.config.range_max)
            np.minimum.at(shadow_from, j[inside], rr[inside])
        shadows = shadow_from if np.isfinite(shadow_from).any() else None
        self._structure_cache = (key, field, shadows)
        return field, shadows

    def _deposit(self, flat: np.ndarray, r: np.ndarray, theta: np.ndarray, amp: np.ndarray) -> None:
        """Add point echoes (complex amplitudes ``amp`` at ranges ``r``, bearings ``theta``) to the flat
        field, spread across beams by the beam pattern and across bins by the pulse."""
        g = self.geometry
        nb, nr = g.n_beams, g.n_bins
        jf = (theta - g.angle_min) / g.angle_increment
        if_ = (r - g.range_min) / self.config.bin_size
        j0, i0 = np.rint(jf).astype(np.int64), np.rint(if_).astype(np.int64)
        tb, tp = self.beam_half_taps, self.bin_half_taps
        near = (j0 >= -tb) & (j0 < nb + tb) & (i0 >= -tp) & (i0 < nr + tp) & (amp != 0)
        if not near.any():
            return
        jf, if_, j0, i0, amp = jf[near], if_[near], j0[near], i0[near], amp[near]
        jj = j0[:, None] + np.arange(-tb, tb + 1)
        ii = i0[:, None] + np.arange(-tp, tp + 1)
        hb = self.pattern((jj - jf[:, None]) * g.angle_increment)
        hp = self._pulse(ii - if_[:, None])
        values = (amp[:, None, None] * hp[:, :, None]) * hb[:, None, :]
        ok = ((ii >= 0) & (ii < nr))[:, :, None] & ((jj >= 0) & (jj < nb))[:, None, :]
        index = (ii[:, :, None] * nb + jj[:, None, :])[ok]
        values = values[ok]
        if index.size < flat.size // 8:
            np.add.at(flat, index, values.astype(np.complex64))
        else:  # many scatterers (walls): one pass over the frame is cheaper
            flat += (np.bincount(index, weights=values.real, minlength=flat.size)
                     + 1j * np.bincount(index, weights=values.imag, minlength=flat.size)).astype(np.complex64)

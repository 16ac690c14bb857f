"""Echo intensity of real sonar sectors: decoding to linear amplitude, noise floor, range gating.

Both papers work on linear echo amplitude (the ESC paper's eqs. 13-15 are laws of the amplitude;
the FLS paper's eq. 1 filters it). Real drivers rarely publish that: Tritech and Ping360 bins are
8-bit counts of a log-compressed (dB) amplitude, imaging sonars publish 8- or 16-bit display
values, and the near field rings. This module is the one place that turns what a sensor sends
into the linear amplitude the algorithms expect; the importer (``sonar_import``) and both
front ends (``active_detector``, ``fls_features``) call it with the same :class:`IntensityConfig`.

Codings (``coding``):

* ``linear_amplitude``: values are the amplitude (the simulator's ``32FC1``, the default);
* ``linear_power``: values are echo power; amplitude = sqrt(power);
* ``db``: values are a log-compressed amplitude. Integer images map their full count range
  (255 for ``mono8``, 65535 for ``mono16``) onto ``db_span`` dB, so a count ``c`` is
  ``c * db_span / full_scale`` dB; float images carry dB directly. Amplitude = 10^(dB / 20),
  relative to the level of count 1;
* ``display``: values are display brightness with gamma ``gamma``: amplitude =
  (c / full_scale)^gamma (floats taken as already in [0, 1]).

An exact zero count stays 0: a sensor that reports 0 measured nothing there (below its gain floor,
or a blanked cell), which is not the same as a weak echo (float dB values have no such count: 0 dB
is a level). Only ``db`` values may be negative. Cells at or below
``noise_floor`` (linear amplitude, after decoding) are set to 0 as well. Rows nearer than
``blank_range`` (transducer ringdown) are set to 0, and rows beyond ``max_range`` are cut off.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.sector import SectorGeometry

__all__ = ['CODINGS', 'IntensityConfig', 'decode', 'encode_db', 'full_scale_of', 'gate_ranges', 'condition',
           'zero_floor']

CODINGS = ('linear_amplitude', 'linear_power', 'db', 'display')


@dataclass(frozen=True)
class IntensityConfig(Config):
    """How a sensor's intensity values become linear echo amplitude, and which ranges count."""

    coding: str = setting('linear_amplitude', 'what the sector values are: linear_amplitude, linear_power, db '
                          '(log-compressed counts) or display (gamma-coded brightness)', choices=CODINGS)
    db_span: float = setting(60.0, 'db coding: the dB range that the full count range spans (255 for mono8, '
                             '65535 for mono16)', unit='dB', low=1.0, high=200.0)
    gamma: float = setting(2.2, 'display coding: amplitude = (value / full scale)^gamma', low=0.1, high=10.0)
    noise_floor: float = setting(0.0, 'decoded amplitudes at or below this are no echo (set to 0)', low=0.0,
                                 high=1e12)
    blank_range: float = setting(0.0, 'cells nearer than this are no echo (transducer ringdown)', unit='m',
                                 low=0.0, high=1e5)
    max_range: float = setting(0.0, 'cells beyond this range are cut off; 0 = keep every range bin', unit='m',
                               low=0.0, high=1e5)

    def validate(self) -> None:
        if self.max_range and self.max_range <= self.blank_range:
            raise ConfigError(f'max_range = {self.max_range} m must be 0 (no limit) or beyond blank_range = '
                              f'{self.blank_range} m')


def full_scale_of(dtype: np.dtype) -> float | None:
    """The count of full scale for an integer image dtype (255, 65535), None for floats."""
    dtype = np.dtype(dtype)
    return float(np.iinfo(dtype).max) if dtype.kind in 'ui' else None


def decode(values: np.ndarray, coding: str = 'linear_amplitude', *, db_span: float = 60.0, gamma: float = 2.2,
           full_scale: float | None = None) -> np.ndarray:
    """Linear echo amplitude (float64, a new array) of sensor values in ``coding``.

    ``full_scale`` is the count of full scale of an integer image (:func:`full_scale_of`); None
    for float values. Exact zero counts stay 0. Raises ValueError for an unknown coding.
    8- and 16-bit counts are looked up in a table of every count's value (the same numbers).
    """
    raw = np.asarray(values)
    if raw.dtype in (np.uint8, np.uint16):
        table = _count_table(raw.dtype.str, coding, float(db_span), float(gamma), full_scale)
        return table[raw]
    return _decode(raw, coding, db_span, gamma, full_scale)


@functools.lru_cache(maxsize=16)
def _count_table(dtype: str, coding: str, db_span: float, gamma: float, full_scale: float | None) -> np.ndarray:
    """The decoded value of every count of an unsigned integer dtype."""
    counts = np.arange(np.iinfo(np.dtype(dtype)).max + 1, dtype=np.float64)
    table = _decode(counts, coding, db_span, gamma, full_scale)
    table.setflags(write=False)
    return table


def _decode(values: np.ndarray, coding: str, db_span: float, gamma: float, full_scale: float | None) -> np.ndarray:
    """:func:`decode` by its formulas."""
    v = np.asarray(values, dtype=np.float64)
    if coding == 'linear_amplitude':
        return v.copy()
    if coding == 'linear_power':
        return np.sqrt(np.maximum(v, 0.0))
    if coding == 'db':
        if not full_scale:
            return np.power(10.0, v / 20.0)   # float dB: 0 dB is a level like any other
        step = db_span / full_scale
        # relative to count 1, so the weakest reported echo is about 1; count 0 is no echo
        out = np.power(10.0, (v - 1.0) * (step / 20.0))
    elif coding == 'display':
        scaled = np.clip(v / full_scale, 0.0, None) if full_scale else np.clip(v, 0.0, None)
        out = np.power(scaled, gamma)
    else:
        raise ValueError(f'unknown intensity coding {coding!r}; one of {list(CODINGS)}')
    out[v == 0.0] = 0.0
    return out


def encode_db(amplitude: np.ndarray, db_span: float = 60.0, full_scale: int = 255,
              reference: float = 1.0) -> np.ndarray:
    """Log-compressed integer counts of linear amplitudes: the inverse of :func:`decode` with ``db``.

    Count 1 is the amplitude ``reference`` (the sensor's gain floor) and each further count is
    ``db_span / full_scale`` dB more, rounded to the nearest count and clipped at ``full_scale``;
    amplitudes more than half a count below ``reference`` (and non-finite or negative values)
    are 0, no echo. ``decode(encode_db(a, ...), 'db', ...)`` is ``a / reference`` within half a
    count. Returns uint8 for ``full_scale`` 255, uint16 up to 65535.
    """
    if not 1 <= full_scale <= 65535:
        raise ValueError(f'full_scale = {full_scale} must be in [1, 65535]')
    a = np.asarray(amplitude, dtype=np.float64)
    step = db_span / full_scale
    with np.errstate(divide='ignore', invalid='ignore'):
        counts = 1.0 + np.rint(20.0 * np.log10(a / reference) / step)
    counts = np.where(np.isfinite(counts) & (counts >= 1.0), np.minimum(counts, full_scale), 0.0)
    return counts.astype(np.uint8 if full_scale <= 255 else np.uint16)


def zero_floor(config: IntensityConfig, dtype: np.dtype) -> float:
    """The decoded amplitude below which a sensor of ``config`` sending ``dtype`` values reports 0.

    Integer counts round to the nearest count, so a zero stands for anything below half a count
    above 0: ``10^(-step / 40)`` with ``db`` coding (count 1 decodes to 1), ``(0.5 / full scale)^gamma``
    with ``display``; ``noise_floor`` when it is higher; 0 for float values without a noise floor
    (a zero there is no data, not a weak echo).
    """
    full = full_scale_of(dtype)
    floor = 0.0
    if full and config.coding == 'db':
        floor = 10.0 ** (-0.5 * (config.db_span / full) / 20.0)
    elif full and config.coding == 'display':
        floor = (0.5 / full) ** config.gamma
    elif full and config.coding == 'linear_power':
        floor = math.sqrt(0.5)
    elif full:
        floor = 0.5
    return max(floor, config.noise_floor)


def gate_ranges(geometry: SectorGeometry, blank_range: float, max_range: float) -> tuple[int, int]:
    """Rows ``[first, stop)`` of the sector that lie in ``[blank_range, max_range]`` (0 = no limit).

    Rows before ``first`` are blanked, rows from ``stop`` on are cut off. ``stop`` is at least 1,
    so a sector is never cut to nothing.
    """
    ranges = geometry.ranges()
    first = int(np.searchsorted(ranges, blank_range, side='left')) if blank_range > 0 else 0
    stop = int(np.searchsorted(ranges, max_range, side='right')) if max_range > 0 else geometry.n_bins
    return min(first, geometry.n_bins), max(stop, 1)


def condition(values: np.ndarray, geometry: SectorGeometry,
              config: IntensityConfig) -> tuple[np.ndarray, SectorGeometry]:
    """Decode a sector to linear amplitude, floor it, blank the near field and cut at ``max_range``.

    Returns ``(amplitudes, geometry)``: float64 amplitudes of shape ``geometry.shape`` (the
    returned geometry has fewer bins when ``max_range`` cut some). The input is not modified.
    """
    a = np.asarray(values)
    if a.shape != geometry.shape:
        raise ValueError(f'values have shape {a.shape}, geometry says {geometry.shape}')
    amplitude = decode(a, config.coding, db_span=config.db_span, gamma=config.gamma,
                       full_scale=full_scale_of(a.dtype))
    if config.noise_floor > 0:
        amplitude[amplitude <= config.noise_floor] = 0.0
    first, stop = gate_ranges(geometry, config.blank_range, config.max_range)
    amplitude[:first] = 0.0
    if stop < geometry.n_bins:
        amplitude = amplitude[:stop]
        top = geometry.ranges()[stop - 1] if stop > 1 else geometry.range_min
        geometry = dataclasses.replace(geometry, n_bins=stop, range_max=float(top))
    return amplitude, geometry


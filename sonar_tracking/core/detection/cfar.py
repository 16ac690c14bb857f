"""CFAR detection on the polar image of an imaging sonar: cell-averaging, greatest-of, ordered-statistic.

A cell of echo intensity ``P`` (linear power: the square of the decoded amplitude) is a detection
when ``P > alpha * Z``, where ``Z`` is the level of its training cells (the package's local-background
rule, :mod:`sonar_tracking.core.background`: guard and training cells in bins and beams, a stride,
no-data cells left out) and ``alpha`` the scale. For clutter of exponential intensity (fully
developed speckle, Rayleigh amplitude) and ``N`` independent training cells the false-alarm
probability is a function of ``alpha`` alone, whatever the clutter level (Gandhi and Kassam 1988;
Rohling 1983):

* ``ca``, ``Z`` the mean of the ``N`` cells:  ``P_fa = (1 + alpha / N)^(-N)``;
* ``go``, ``Z`` the greater of the means of the nearer and the farther half (``n = N / 2`` each):
  ``P_fa = 2 (1 + alpha/n)^(-n) - 2 sum_{k=0}^{n-1} C(n-1+k, k) (2 + alpha/n)^(-(n+k))``;
* ``os``, ``Z`` the ``k``-th smallest of the ``N`` cells:
  ``P_fa = prod_{i=0}^{k-1} (N - i) / (N - i + alpha)``.

:func:`design_scale` inverts these for a design ``P_fa``. A cell near the sector's edge or among
no-data cells has fewer training cells; it is tested with the scale of its own count, so the design
``P_fa`` holds at every cell (cells below the sensor's floor count as no data, and the level comes
from the measured cells' excess over the floor, which keeps it unbiased; ``go`` with unequal halves
takes the scale of the smaller half, a slightly lower ``P_fa``; with one half empty it is ``ca`` on
the other). A cell with fewer than ``min_train`` of the nominal training cells measured is not
tested.

The detector thresholds the *CFAR-normalised* image ``q = P / (Z c)``, where ``c`` is the cell's
scale over the nominal one at the design ``P_fa`` (:meth:`Cfar.normalise`): ``q > alpha_0`` is the
test above at every cell, and extremum-seeking control moves the one scale ``alpha`` (the
detector's threshold) from ``alpha_0`` to hold a desired false-detection density where the clutter
is not exponential (K-distributed clutter gives cell-averaging CFAR many more false alarms than
designed).

``ca`` normalises a frame in one compiled pass over the window sums (:func:`_ca_normalise`) with
the array formula's arithmetic, to the last bit, fast enough for an imaging sonar's 512 x 1000
cells at 20 Hz.

Correlated cells: an imaging sonar forms more beams than its beam width resolves, and a pulse spans
several fine range bins, so neighbouring cells are correlated. The formulas hold for independent
training cells: set the strides to about one resolution cell (beam width over beam spacing, pulse
length over bin size) and the guard to cover the main lobe and the pulse.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import gammaln

from sonar_tracking.core.background import Window, measured, window_order, window_sums
from sonar_tracking.core.config import Config, ConfigError, setting
from sonar_tracking.core.jit import kernel

__all__ = ['CFAR_METHODS', 'MAX_TRAINING_CELLS', 'CfarConfig', 'Cfar', 'pfa', 'design_scale']

CFAR_METHODS = ('ca', 'go', 'os')
#: Most training cells a window may hold: the scale tables and the per-frame work grow with it.
MAX_TRAINING_CELLS = 1000


def pfa(method: str, n: int, alpha: float, rank: int = 0) -> float:
    """False-alarm probability of ``method`` with ``n`` training cells at scale ``alpha`` (module
    docstring); ``rank`` is OS's ``k``; ``go`` takes ``n`` as the cells of one half."""
    if alpha < 0:
        raise ValueError(f'alpha = {alpha} must be >= 0')
    if method == 'ca':
        return math.exp(-n * math.log1p(alpha / n))
    if method == 'go':
        a = alpha / n
        k = np.arange(n)
        log_terms = gammaln(n + k) - gammaln(k + 1) - gammaln(n) - (n + k) * math.log(2.0 + a)
        so = 2.0 * float(np.exp(log_terms).sum())
        return max(2.0 * math.exp(-n * math.log1p(a)) - so, 0.0)
    if method == 'os':
        if not 1 <= rank <= n:
            raise ValueError(f'OS rank {rank} must lie in 1..{n}')
        i = np.arange(rank)
        return float(np.exp(np.sum(np.log(n - i) - np.log(n - i + alpha))))
    raise ValueError(f'unknown CFAR method {method!r}; known: {CFAR_METHODS}')


def design_scale(method: str, n: int, target: float, rank: int = 0) -> float:
    """The scale ``alpha`` at which ``method`` with ``n`` training cells (``go``: per half; ``os``:
    rank ``rank``) has false-alarm probability ``target``."""
    if not 0 < target < 1:
        raise ValueError(f'design P_fa = {target} must lie in (0, 1)')
    if n < 1:
        raise ValueError('CFAR needs at least one training cell')

    def gap(log_alpha: float) -> float:
        return math.log(max(pfa(method, n, math.exp(log_alpha), rank), 1e-300)) - math.log(target)
    hi = 1.0
    while gap(hi) > 0:
        hi += 2.0
        if hi > 60:
            raise ValueError(f'{method} with {n} training cells cannot reach P_fa = {target}')
    return math.exp(brentq(gap, -30.0, hi, xtol=1e-12, rtol=1e-12))


@dataclass(frozen=True)
class CfarConfig(Config):
    """Window and design false-alarm probability of CFAR (bins: range bins; beams: image columns)."""

    pfa: float = setting(1e-4, 'design false-alarm probability per cell (sets the initial scale alpha_0)',
                         low=1e-12, high=0.5)
    guard_bins: int = setting(2, 'guard cells on each side of the cell under test, in range bins', low=0, high=200)
    guard_beams: int = setting(2, 'guard cells on each side, in beams', low=0, high=200)
    reach_bins: int = setting(12, 'training cells reach this many range bins from the cell under test', low=0,
                              high=400)
    reach_beams: int = setting(12, 'training cells reach this many beams from the cell under test', low=0, high=400)
    stride_bins: int = setting(2, 'training cells every this many range bins (about the pulse length in bins)',
                               low=1, high=64)
    stride_beams: int = setting(2, 'training cells every this many beams (about the beam width over the beam '
                                'spacing)', low=1, high=64)
    os_rank: float = setting(0.75, 'os: the order statistic as a fraction of the training cells (k = round(fN))',
                             low=0.0, low_open=True, high=1.0)
    min_train: float = setting(0.5, 'a cell is tested only when at least this share of its nominal training cells '
                               'is measured', low=0.0, low_open=True, high=1.0)

    def validate(self) -> None:
        try:
            w = self.window()
        except ValueError as exc:
            raise ConfigError(f'cfar window: {exc}') from None
        if w.size < 4:
            raise ConfigError(f'the cfar window holds {w.size} training cells; widen reach_bins/reach_beams '
                              '(at least 4)')
        if w.size > MAX_TRAINING_CELLS:
            raise ConfigError(f'the cfar window holds {w.size} training cells, more than {MAX_TRAINING_CELLS}; '
                              'narrow reach_bins/reach_beams or widen the strides')

    def window(self) -> Window:
        """The training window these settings describe."""
        return Window(self.guard_bins, self.guard_beams, self.reach_bins, self.reach_beams, self.stride_bins,
                      self.stride_beams)


class Cfar:
    """CFAR of one method and window: the design scale and the CFAR-normalised image."""

    def __init__(self, method: str, config: CfarConfig) -> None:
        if method not in CFAR_METHODS:
            raise ConfigError(f'unknown CFAR method {method!r}; known: {CFAR_METHODS}')
        self.method = method
        self.config = config
        self.window = config.window()
        n = self.window.size
        self.rank = max(1, min(n, round(config.os_rank * n)))
        self.min_count = max(1, math.ceil(config.min_train * n))
        per = n // 2 if method == 'go' else n
        self.alpha0 = design_scale(method, per, config.pfa, self.rank)
        self._ratio = self._ratios()
        self._go_table = self._go_ratios() if method == 'go' else np.zeros((0, 0))

    @property
    def training_cells(self) -> int:
        """Training cells of a cell away from the edges."""
        return self.window.size

    def _ratios(self) -> np.ndarray:
        """Scale at the design P_fa for each possible count, over the nominal ``alpha0`` (inf where the
        cell is not tested). ``ca``/``go``: indexed by measured cells (``go``: of the smaller half,
        or of the whole window for ``ca`` on one half); ``os``: by the number of unmeasured cells."""
        c, n = self.config, self.window.size
        ratio = np.full(n + 1, np.inf)
        for m in range(n + 1):
            if self.method == 'os':
                valid, k = n - m, self.rank - m
                if valid >= self.min_count and k >= 1:
                    ratio[m] = design_scale('os', valid, c.pfa, k) / self.alpha0
            elif m >= 1 and (self.method == 'go' or m >= self.min_count):
                ratio[m] = design_scale('ca', m, c.pfa) / self.alpha0
        return ratio

    def level(self, power: np.ndarray, floor: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The training level ``Z`` of every cell and its scale ratio ``c`` (inf: not tested); ``floor``:
        the intensity below which the sensor reports 0 (:mod:`sonar_tracking.core.background`, rule 1)."""
        if self.method == 'os':
            stat, missing = window_order(power, self.window, self.rank, floor)
            return stat, self._ratio[missing.astype(np.int64)]
        sums = window_sums(power, self.window, halves=self.method == 'go', floor=floor)
        with np.errstate(invalid='ignore', divide='ignore'):
            if self.method == 'ca':
                count = sums.count.astype(np.intp)
                return sums.total / np.maximum(sums.count, np.float32(1.0)), self._ratio[count]
            near, far = sums.near_count, sums.far_count
            level = np.fmax(sums.near_total / near, sums.far_total / far)   # 0 / 0 is NaN: the other half
        index = near.astype(np.intp) * self._go_table.shape[1] + far.astype(np.intp)
        return level, self._go_table.reshape(-1)[index]

    def _go_ratios(self) -> np.ndarray:
        """GO scale over ``alpha0`` by the counts of the nearer and the farther half: the GO scale of
        the smaller half, or CA's of the one measured half; inf below ``min_train``."""
        half = self.window.size // 2
        go = [np.inf] + [design_scale('go', m, self.config.pfa) / self.alpha0 for m in range(1, half + 1)]
        table = np.full((half + 1, half + 1), np.inf)
        for n1 in range(half + 1):
            for n2 in range(half + 1):
                if n1 + n2 >= self.min_count:
                    table[n1, n2] = go[min(n1, n2)] if n1 and n2 else self._ratio[n1 + n2]
        return table

    def normalise(self, power: np.ndarray, floor: float = 0.0) -> np.ndarray:
        """The CFAR-normalised image ``q = P / (Z c)`` (float32): NaN where a cell is not tested (too
        few measured training cells, or no measurement of its own), 0 where it reads 0 below a
        ``floor`` (the intensity below which the sensor reports 0: such a cell was measured, weak).
        ``q > alpha0`` is the design test at every tested cell; a threshold ``alpha`` on ``q`` is that
        test at another scale."""
        p = np.asarray(power, dtype=np.float32)
        if self.method == 'ca' and p.ndim == 2 and p.size:
            p = np.ascontiguousarray(p)
            sums = window_sums(p, self.window, floor=floor)
            q = np.empty(p.shape, np.float32)
            _ca_normalise(p, sums.total, sums.count, self._ratio, float(floor), q)
            return q
        z, ratio = self.level(p, floor)
        with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
            denom = z * ratio
            tested = np.isfinite(denom) & (denom > 0) & (measured(p) | (floor > 0) & np.isfinite(p))
            q = np.where(tested, p / np.where(tested, denom, 1.0), np.nan)
        return q.astype(np.float32)


@kernel
def _ca_normalise(power, total, count, ratio, floor, out):
    """:meth:`Cfar.normalise` for ``ca`` in one pass, with the same arithmetic as its array code: the
    level ``Z`` = total / max(count, 1) in float32, ``Z c`` and ``P / (Z c)`` in float64, rounded to
    float32; NaN where the cell is not tested."""
    one = np.float32(1.0)
    n_rows, n_cols = power.shape
    for y in range(n_rows):
        for x in range(n_cols):
            p = power[y, x]
            c = count[y, x]
            z = total[y, x] / (c if c > one else one)
            denom = np.float64(z) * ratio[np.intp(c)]
            data = np.isfinite(p) and (p != 0 or floor > 0)
            if data and np.isfinite(denom) and denom > 0:
                out[y, x] = np.float32(np.float64(p) / denom)
            else:
                out[y, x] = np.nan

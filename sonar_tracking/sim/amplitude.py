"""Echo amplitude statistics of clutter and targets (ESC paper §2.3).

Clutter cell amplitude follows the exponential law of eq. (15), ``p(s) = lam * exp(-lam * s)``,
so a threshold ``tau`` gives ``P_fa = exp(-lam * tau)`` (eq. 16). A target cell is exponential
with mean ``(1 + SNR) / lam`` (a fluctuating, Swerling-I-like target), so
``P_D = exp(-lam * tau / (1 + SNR))``, which is Algorithm 1, line 3: ``P_fa = P_D ** (1 + SNR)``.

Rayleigh (eq. 13) and Weibull (eq. 14) clutter are options; they are scaled so that their mean is
``1 / lam`` too, which keeps ``lam`` the one knob for how much clutter a region has.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sonar_tracking.core.config import Config, ConfigError, setting

__all__ = ['AmplitudeConfig', 'AmplitudeModel', 'exponential_pfa', 'exponential_pd', 'snr_linear']


def snr_linear(snr_db: float) -> float:
    """SNR as a power ratio, ``10 ** (snr_db / 10)``."""
    return 10.0 ** (snr_db / 10.0)


def exponential_pfa(lam: float | np.ndarray, tau: float | np.ndarray) -> float | np.ndarray:
    """False-alarm probability of exponential clutter, eq. (16): ``exp(-lam * tau)``."""
    return np.exp(-np.asarray(lam) * np.asarray(tau))


def exponential_pd(lam: float | np.ndarray, tau: float | np.ndarray, snr_db: float) -> float | np.ndarray:
    """Detection probability of an exponential target cell: ``exp(-lam * tau / (1 + SNR))``."""
    return np.exp(-np.asarray(lam) * np.asarray(tau) / (1.0 + snr_linear(snr_db)))


@dataclass(frozen=True)
class AmplitudeConfig(Config):
    """Clutter amplitude law."""

    distribution: str = setting('exponential', 'clutter amplitude law (eq. 15, 13 or 14)',
                                choices=('exponential', 'rayleigh', 'weibull'))
    weibull_shape: float = setting(1.5, 'Weibull shape c of eq. (14)', low=0.1, high=10.0)


class AmplitudeModel:
    """Samples cell amplitudes with mean ``1 / lam`` (clutter) or ``(1 + SNR) / lam`` (target)."""

    def __init__(self, config: AmplitudeConfig | None = None) -> None:
        self.config = config or AmplitudeConfig()
        c = self.config
        if c.distribution == 'rayleigh':
            self._unit_mean = math.sqrt(math.pi / 2.0)
        elif c.distribution == 'weibull':
            self._unit_mean = math.gamma(1.0 + 1.0 / c.weibull_shape)
        else:
            self._unit_mean = 1.0

    def unit(self, rng: np.random.Generator, size: int | tuple[int, ...]) -> np.ndarray:
        """Samples of mean 1 of the configured law (float64)."""
        c = self.config
        if c.distribution == 'exponential':
            return rng.standard_exponential(size)
        if c.distribution == 'rayleigh':
            return rng.rayleigh(1.0, size) / self._unit_mean
        if c.distribution == 'weibull':
            return rng.weibull(c.weibull_shape, size) / self._unit_mean
        raise ConfigError(f'unknown distribution {c.distribution!r}')  # pragma: no cover

    def clutter(self, lam: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Clutter amplitudes for cells of rate ``lam`` (array of any shape)."""
        lam = np.asarray(lam, dtype=float)
        return self.unit(rng, lam.shape) / lam

    def target(self, lam: np.ndarray, snr_db: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Target-cell amplitudes: exponential with mean ``(1 + SNR) / lam`` (whatever the clutter law)."""
        lam = np.asarray(lam, dtype=float)
        snr = 10.0 ** (np.asarray(snr_db, dtype=float) / 10.0)
        return rng.standard_exponential(np.broadcast(lam, snr).shape) * (1.0 + snr) / lam

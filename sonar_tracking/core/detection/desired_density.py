"""The desired clutter density table of ESC paper §4 (Algorithm 1): rho_D as a function of SNR.

The table (``config/desired_density.yaml``, made by ``sonar_eval desired-density``) lists
``snr_db`` and ``desired_clutter_density`` pairs; :meth:`DesiredDensityTable.lookup` interpolates
``log(rho_D)`` linearly in SNR [dB] between entries and refuses SNRs outside the table.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from sonar_tracking.core.config import ConfigError

__all__ = ['DesiredDensityTable', 'TableError', 'resolve_desired_density']


class TableError(ValueError):
    """The table is missing, malformed, or does not cover the requested SNR."""


@dataclass(frozen=True, eq=False)
class DesiredDensityTable:
    """Sorted SNR [dB] and desired densities [1/m^2]."""

    snr_db: np.ndarray
    density: np.ndarray
    source: str = ''

    def __post_init__(self) -> None:
        if len(self.snr_db) < 1 or len(self.snr_db) != len(self.density):
            raise TableError('a desired-density table needs matching, non-empty SNR and density columns')
        if np.any(np.diff(self.snr_db) <= 0):
            raise TableError('table SNRs must increase')
        if not np.all((self.density > 0) & np.isfinite(self.density)):
            raise TableError('table densities must be finite and > 0')

    @classmethod
    def load(cls, path: str | Path) -> DesiredDensityTable:
        """Read ``entries: [{snr_db: ..., desired_clutter_density: ...}, ...]`` from YAML."""
        try:
            data = yaml.safe_load(Path(path).read_text())
            rows = sorted((float(e['snr_db']), float(e['desired_clutter_density'])) for e in data['entries'])
        except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
            raise TableError(f'cannot read desired-density table {path}: {exc}') from exc
        return cls(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), str(path))

    def lookup(self, snr_db: float) -> float:
        """rho_D at ``snr_db``, interpolated in log density."""
        lo, hi = self.snr_db[0], self.snr_db[-1]
        if not lo - 1e-9 <= snr_db <= hi + 1e-9:
            raise TableError(f'SNR {snr_db:g} dB is outside the table ({lo:g} to {hi:g} dB) in {self.source}')
        return float(math.exp(np.interp(snr_db, self.snr_db, np.log(self.density))))


def resolve_desired_density(config, table: Callable[[], str | Path]) -> float:
    """rho_D of a detector ``config``: ``esc.desired_clutter_density``, or when that is 0 the table
    (``table()``: its path) at ``esc.snr_db`` (Algorithm 1). ConfigError says why when neither serves."""
    if config.esc.desired_clutter_density > 0:
        return config.esc.desired_clutter_density
    try:
        return DesiredDensityTable.load(table()).lookup(config.esc.snr_db)
    except (FileNotFoundError, TableError) as exc:
        raise ConfigError(f'esc.desired_clutter_density = 0 asks for the desired-density table, but: {exc}') from None

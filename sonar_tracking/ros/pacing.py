"""The pace and the stamps of a source that publishes simulated time (``seaking_sim``).

``rate`` 1 publishes in real time, 2 twice as fast, 0 as fast as the readers take it. The stamps
are the wall clock at which a message is due (``wall``), or simulated time from an offset
(``sim``, with ``/clock`` published so ``use_sim_time`` nodes and bags agree).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from sonar_tracking.core.config import Config, setting

__all__ = ['PacingConfig', 'Pacer']


@dataclass(frozen=True)
class PacingConfig(Config):
    """How a source of simulated time publishes: pace, stamps, and when it starts and ends."""

    rate: float = setting(1.0, 'pace: 1 = real time, 2 = twice as fast, 0 = as fast as subscribers take it',
                          low=0.0, high=1e4)
    stamps: str = setting('auto', 'clock of the stamps: wall, sim (simulated time, with /clock), or auto (wall when '
                          'starting at rate 1, else sim)', choices=('auto', 'wall', 'sim'), read_only=True)
    stamp_offset: float = setting(0.0, 'stamp of the scenario start with sim stamps', unit='s', low=0.0, high=4e9,
                                  read_only=True)
    publish_clock: bool = setting(False, 'publish /clock with wall stamps too (it is always published with sim '
                                  'stamps)', read_only=True)
    shutdown_when_done: bool = setting(False, 'exit once the scenario has ended', read_only=True)
    wait_for_subscribers: int = setting(0, 'start once /sonar/sector and /sonar/sector_info have this many '
                                        'subscribers and every subscriber in the graph is connected (0 = at once)',
                                        low=0, high=1000, read_only=True)
    start_settle_time: float = setting(1.0, 'with wait_for_subscribers: how long the graph must stay connected '
                                       'before the start (3.5 s for subscribers of tools that announce every 3 s)',
                                       unit='s', low=0.0, high=60.0, read_only=True)


class Pacer:
    """When each simulated instant is due on the wall clock, and the stamp it carries."""

    def __init__(self, config: PacingConfig, sim_now: float) -> None:
        self.rate, self.stamp_offset = config.rate, config.stamp_offset
        self.wall_stamps = config.stamps == 'wall' or (config.stamps == 'auto' and config.rate == 1.0)
        self.anchor(sim_now)

    def anchor(self, sim_now: float, rate: float | None = None) -> None:
        """Tie simulated time ``sim_now`` to now (at start, while waiting, and when ``rate`` changes)."""
        self.rate = self.rate if rate is None else rate
        self._wall0, self._epoch0_ns, self._sim0 = time.monotonic(), time.time_ns(), sim_now

    def due(self, sim_t: float) -> bool:
        """Whether simulated time ``sim_t`` is due now (always with ``rate`` 0)."""
        return self.rate == 0 or time.monotonic() >= self._wall0 + (sim_t - self._sim0) / self.rate

    def stamp_ns(self, sim_t: float) -> int:
        """The stamp of simulated time ``sim_t``: the wall time it is due at, or simulated time."""
        if not self.wall_stamps:
            return int(round((self.stamp_offset + sim_t) * 1e9))
        if self.rate == 0:
            return time.time_ns()
        return self._epoch0_ns + int(round((sim_t - self._sim0) / self.rate * 1e9))

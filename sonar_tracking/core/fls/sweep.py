"""Where a sweep of a mechanically scanned sonar begins and ends, from the sector geometry alone.

The sector messages do not say "end of sweep", so the image builder infers it (FLS paper §2: the
head "continues until the entire sector is scanned", then the image is complete):

* all beams at once (``ping_period == 0``, a multibeam or a harbour scan): every sector is a
  whole image;
* sector mode (back and forth): the head reverses at the limits. A reversal (the sign of the ping
  period flips) starts a new sweep, and the bearing pinged last before it is remembered as a
  limit; from then on a sector that reaches a known limit ends its sweep at once, so the image is
  emitted without waiting for the next sector;
* continuous rotation: a sweep ends once the pinged bearings cover a full turn.

A sector that does not continue the last one (a lost sector, a jump) stays in the current sweep:
an image with a gap is better than none.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from sonar_tracking.core.sector import SectorGeometry

__all__ = ['SweepTracker', 'SweepStep']

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class SweepStep:
    """What a sector means for the sweep: it starts a new one, and/or it completes the current one."""

    starts: bool
    ends: bool


class SweepTracker:
    """Follows the head from sector to sector; :meth:`update` classifies each new sector."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the head's history (after a geometry change or time going backwards)."""
        self._direction = 0          # +1 increasing bearing, -1 decreasing, 0 none yet / all at once
        self._last = math.nan        # bearing pinged last [rad]
        self._span = 0.0             # bearing swept since the sweep began [rad]
        self._limits: dict[int, float] = {}  # direction -> bearing where the head reversed
        self._ended = True           # the previous sector completed a sweep

    def update(self, geometry: SectorGeometry) -> SweepStep:
        """Classify the next sector (in arrival order) and advance the state."""
        inc = geometry.angle_increment
        if geometry.ping_period == 0.0:
            self._ended, self._direction = True, 0
            return SweepStep(starts=True, ends=True)
        d = 1 if geometry.ping_period > 0 else -1
        first, last = (geometry.angle_min, geometry.angle_max) if d > 0 else (geometry.angle_max, geometry.angle_min)
        reversed_ = self._direction != 0 and d != self._direction
        if reversed_:
            self._limits[self._direction] = self._last
        starts = self._ended or reversed_ or self._direction == 0
        if starts:
            self._span = abs(geometry.angle_max - geometry.angle_min)
        else:
            # Swept angle in the direction of travel, wrapping through +/- pi.
            step = (d * (last - self._last)) % _TWO_PI
            self._span += step
        self._direction, self._last = d, last
        at_limit = d in self._limits and abs(math.remainder(last - self._limits[d], _TWO_PI)) < 0.5 * inc
        ends = at_limit or self._span >= _TWO_PI - 1.5 * inc
        self._ended = ends
        return SweepStep(starts=starts, ends=ends)

"""Per-ping scanning sonars: pings grouped into sectors of the package's contract (DESIGN §4).

A mechanically scanned head (Tritech Micron/SeaKing, Ping360) sends one ping per head step.
:class:`SweepAssembler` takes the pings in recording order and returns sectors whose columns are
beams in increasing bearing (counter-clockwise from x, REP-103):

* a sweep ends where the head reverses (back-and-forth sector scans), where it has covered a full
  turn (continuous rotation), where the step, the range bins, the sample count or the settings
  (:attr:`Ping.settings`) change, where
  pings are missing (the bearing jumps by more than one step) and where the time between two pings
  exceeds ``max_gap``; the pings of a sweep are held until it ends (at most one turn), and the
  last, partial sweep is returned by :meth:`SweepAssembler.finish`;
* a sweep is cut into sectors of ``pings_per_sector`` pings (0 = one sector per sweep); every ping
  is in exactly one sector, except a message recorded twice (same stamp, bearing and samples),
  which is dropped and reported;
* a sector swept toward decreasing bearing has its columns reversed: column 0 was pinged last, its
  stamp is that ping's and ``ping_period`` is negative (the LaserScan ``time_increment`` rule);
  otherwise the stamp is the first ping's and the period positive;
* ``scan_time`` is the duration of the sector's sweep (the FLS image keeps two of them).

Cuts that mean something is wrong with the recording (missing pings, a time gap, a ping with
fewer samples than announced) are reported as :class:`Problem`s naming the stamp.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sonar_tracking.core.sector import SectorGeometry

__all__ = ['Ping', 'Sector', 'Problem', 'SweepAssembler']

_TWO_PI = 2.0 * math.pi


@dataclass(eq=False)
class Ping:
    """One ping: stamp and bag time [ns], bearing [rad, REP-103], samples (range bins, nearest first).

    ``range_min``/``range_max`` are the centres of the first and last sample [m]; ``expected`` the
    sample count the message announced (0 = not announced); ``settings`` the sensor settings that
    shape the samples (a Ping360's sample period and count): pings whose settings differ never
    share a sector.
    """

    stamp_ns: int
    log_ns: int
    bearing: float
    samples: np.ndarray
    range_min: float
    range_max: float
    expected: int = 0
    settings: tuple = ()


@dataclass(eq=False)
class Sector:
    """Columns of consecutive pings in increasing bearing; ``log_ns`` = bag time of its last ping."""

    stamp_ns: int
    log_ns: int
    values: np.ndarray
    geometry: SectorGeometry
    n_pings: int


@dataclass(frozen=True)
class Problem:
    """Something wrong in the recording: where (stamp) and what."""

    stamp_ns: int
    message: str


@dataclass(eq=False)
class _Sweep:
    pings: list[Ping] = field(default_factory=list)
    direction: int = 0
    step: float = 0.0
    span: float = 0.0


def _wrap(a: float) -> float:
    return math.remainder(a, _TWO_PI)


class SweepAssembler:
    """Pings in (recording order), sectors out; see the module docstring for the rules."""

    def __init__(self, pings_per_sector: int = 0, max_gap: float = 2.0, step_tolerance: float = 0.25) -> None:
        if pings_per_sector < 0:
            raise ValueError('pings_per_sector must be >= 0 (0 = one sector per sweep)')
        self.pings_per_sector = pings_per_sector
        self.max_gap_ns = int(max_gap * 1e9)
        self.step_tolerance = step_tolerance
        self.problems: list[Problem] = []
        self.pings_in = 0
        self.pings_out = 0
        self.dropped = 0
        self._sweep = _Sweep()
        self._last_direction = 1
        self._last_period = 0.0

    def add(self, ping: Ping) -> list[Sector]:
        """Offer the next ping; returns the sectors of a sweep this ping ended (often none)."""
        self.pings_in += 1
        ping = self._fill(ping)
        sweep = self._sweep
        out: list[Sector] = []
        if sweep.pings and self._repeats(sweep.pings[-1], ping):
            self.dropped += 1
            self.problems.append(Problem(ping.stamp_ns, 'the same ping again (stamp, bearing and samples): dropped'))
            return out
        if sweep.pings and (not self._continues(sweep, ping) or self._turned(sweep, ping)):
            out = self._flush()
            sweep = self._sweep
        if sweep.pings:
            d = abs(_wrap(ping.bearing - sweep.pings[-1].bearing))
            if len(sweep.pings) == 1:
                sweep.direction = 1 if _wrap(ping.bearing - sweep.pings[0].bearing) > 0 else -1
                sweep.step = d
            sweep.span += d
        sweep.pings.append(ping)
        return out

    def finish(self) -> list[Sector]:
        """The sectors of the last (partial) sweep."""
        return self._flush()

    # -- rules -------------------------------------------------------------------------------------

    def _fill(self, ping: Ping) -> Ping:
        """Pad a ping with fewer samples than it announced (0 = nothing measured), and say so."""
        n = len(ping.samples)
        if ping.expected and n < ping.expected:
            self.problems.append(Problem(ping.stamp_ns, f'ping has {n} of its {ping.expected} samples; '
                                                        'the missing far samples are set to 0 (no echo)'))
            padded = np.zeros(ping.expected, dtype=ping.samples.dtype)
            padded[:n] = ping.samples
            ping.samples = padded
        return ping

    @staticmethod
    def _repeats(last: Ping, ping: Ping) -> bool:
        return (ping.stamp_ns == last.stamp_ns and ping.bearing == last.bearing
                and np.array_equal(ping.samples, last.samples))

    @staticmethod
    def _turned(sweep: _Sweep, ping: Ping) -> bool:
        """The ping would reach the sweep's first bearing again (a full turn is complete)."""
        d = abs(_wrap(ping.bearing - sweep.pings[-1].bearing))
        return bool(sweep.direction) and sweep.span + d >= _TWO_PI - 0.5 * sweep.step

    def _continues(self, sweep: _Sweep, ping: Ping) -> bool:
        last = sweep.pings[-1]
        if ping.settings != last.settings or len(ping.samples) != len(last.samples) or not (
                math.isclose(ping.range_min, last.range_min, rel_tol=1e-4, abs_tol=1e-6)
                and math.isclose(ping.range_max, last.range_max, rel_tol=1e-4, abs_tol=1e-6)):
            return False
        dt = ping.stamp_ns - last.stamp_ns
        if dt > self.max_gap_ns or dt < 0:
            self.problems.append(Problem(ping.stamp_ns, f'{dt / 1e9:.3f} s since the previous ping (more than '
                                                        f'{self.max_gap_ns / 1e9:g} s or backwards): new sweep'))
            return False
        d = _wrap(ping.bearing - last.bearing)
        if d == 0.0:
            return False
        if not sweep.direction:
            return True
        if (d > 0) != (sweep.direction > 0):
            return False  # reversal: the normal end of a back-and-forth sweep
        if abs(abs(d) - sweep.step) > self.step_tolerance * sweep.step:
            k = abs(d) / sweep.step
            if k > 1.0 + self.step_tolerance:
                self.problems.append(Problem(ping.stamp_ns, f'bearing jumped {math.degrees(abs(d)):.2f} deg, '
                                                            f'{k:.1f} head steps: about {round(k) - 1} pings '
                                                            'missing; new sweep'))
            return False
        return True

    def _flush(self) -> list[Sector]:
        sweep, self._sweep = self._sweep, _Sweep()
        pings = sweep.pings
        if not pings:
            return []
        if sweep.direction:
            self._last_direction = sweep.direction
        direction = sweep.direction or self._last_direction
        duration = (pings[-1].stamp_ns - pings[0].stamp_ns) / 1e9
        period = duration / (len(pings) - 1) if len(pings) > 1 else self._last_period
        if period > 0:
            self._last_period = period
        period = period if period > 0 else 1e-3  # a lone ping with no history: any positive period
        scan_time = duration + period
        size = self.pings_per_sector or len(pings)
        return [self._sector(pings[i:i + size], direction, sweep.step, period, scan_time)
                for i in range(0, len(pings), size)]

    def _sector(self, pings: list[Ping], direction: int, step: float, period: float, scan_time: float) -> Sector:
        cols = pings if direction > 0 else pings[::-1]
        # Bearings unwrapped from column 0, in increasing order.
        b0 = cols[0].bearing
        offsets = np.array([_wrap(p.bearing - b0) for p in cols])
        offsets = np.where(offsets < -1e-9, offsets + _TWO_PI, offsets)
        n = len(cols)
        inc = float(offsets[-1] / (n - 1)) if n > 1 and offsets[-1] > 0 else (step or math.radians(1.0))
        values = np.stack([p.samples for p in cols], axis=1)
        first = cols[0]
        geom = SectorGeometry(angle_min=_wrap(b0), angle_increment=inc, n_beams=n, range_min=float(first.range_min),
                              range_max=float(first.range_max), n_bins=values.shape[0],
                              ping_period=direction * period, scan_time=scan_time)
        self.pings_out += n
        return Sector(stamp_ns=first.stamp_ns, log_ns=max(p.log_ns for p in pings), values=values, geometry=geom,
                      n_pings=n)

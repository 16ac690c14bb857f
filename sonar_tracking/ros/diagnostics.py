"""``/diagnostics`` of the package's nodes: rates, latency, counts, drops, staleness.

:class:`StageDiagnostics` counts a node's processed messages and its drops by reason and builds the
``DiagnosticArray`` the node publishes (once a second, and at once when its state changes).

* **Rate** (``rate_hz``): processed messages per second over a recent window ending now
  (``max(RATE_WINDOW, RATE_WINDOW_PERIODS`` expected periods), the last ``HISTORY`` inputs at most):
  exact while the input comes, it decays to 0 once the input stops.
* **Expected period** (``expected_period_s``): the median interval between the last
  ``PERIOD_SAMPLES`` processed messages.
* **Staleness**: WARN ``no input for X s`` once no message came (processed or dropped) for
  ``STALE_PERIODS`` = 3 expected periods, and at least ``STALE_MIN`` = 1 s (the report period, so a
  fast input is not flagged between two messages); before the period is known, after
  ``STALE_PERIODS`` seconds. A node that is idle on purpose (a simulator whose scenario ended)
  says so with :attr:`StageDiagnostics.idle` instead.
* **Drops**: WARN when messages were dropped since the last report. Counts are per reason
  (``dropped_REASON``), in the node's input units (a sector is an image and its geometry), except
  the reasons of single messages that never became a unit: ``unpaired``, ``partner_lost``,
  ``evicted``, ``duplicate``, ``bad_stamp`` and ``queue_overflow`` (:class:`SequenceGaps`).
* **Conditions** (:meth:`StageDiagnostics.condition`): standing problems a node reports (a refused
  ``/clock``), shown until cleared.

Level: the worst of the above; STALE before any input; OK otherwise.
"""
from __future__ import annotations

import math
import re
import statistics
import time
from collections import deque
from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

__all__ = ['StageDiagnostics', 'SequenceGaps', 'STALE_PERIODS', 'QUEUE_OVERFLOW']

#: Missed expected periods after which a node reports that its input stopped.
STALE_PERIODS = 3
#: Reason under which messages lost before the node read them are counted.
QUEUE_OVERFLOW = 'queue_overflow'


class StageDiagnostics:
    """Counts inputs, outputs and drops (by reason) and times processing; builds a DiagnosticArray
    (module docstring). ``clock``: the monotonic clock in seconds (injectable for tests); ``what``:
    what the node counts, for the messages (``no input for 4.0 s``, ``no sector yet``)."""

    HISTORY = 200           # processed stamps kept for rate and period
    PERIOD_SAMPLES = 20     # intervals the expected period is the median of
    RATE_WINDOW = 10.0      # s, shortest rate window
    RATE_WINDOW_PERIODS = 10
    STALE_MIN = 1.0         # s
    UNKNOWN_PERIOD = 1.0    # s, assumed before two inputs gave a period

    def __init__(self, name: str, hardware_id: str = 'sonar', clock: Callable[[], float] = time.monotonic,
                 what: str = 'input') -> None:
        self.name = name
        self.hardware_id = hardware_id
        self.what = what   # the noun of the staleness messages
        self.clock = clock
        self.processed = 0
        self.dropped: dict[str, int] = {}
        self._recent_drops = 0
        self._latency: deque[float] = deque(maxlen=self.HISTORY)
        self._stamps: deque[float] = deque(maxlen=self.HISTORY)
        self._last_input: float | None = None
        #: The node's values (replaced by the node as it likes).
        self.values: dict[str, str] = {}
        #: Values of the runtime layer (restarts, parameter changes), kept apart from the node's.
        self.status: dict[str, str] = {}
        self.listeners: dict[str, int] = {}
        #: When not None, the node has no input on purpose; shown instead of a staleness warning.
        self.idle: str | None = None
        self._conditions: dict[str, tuple[bytes, str]] = {}
        self._last_report: dict[str, float] = {}

    def drop(self, reason: str, count: int = 1) -> None:
        """Count ``count`` dropped messages under a short reason key."""
        if count <= 0:
            return
        self.dropped[reason] = self.dropped.get(reason, 0) + count
        self._recent_drops += count
        self._last_input = self.clock()

    def report(self, logger, reason: str, text: str, level: str = 'error', count: int = 1) -> None:
        """Count ``count`` dropped messages and log why: each kind of problem at once, then at most once
        a second (a sensor sending bad data all the time must not flood the log, nor hide a new fault)."""
        self.drop(reason, count)
        self.log(logger, reason + ':' + self.kind(text), text, level)

    @staticmethod
    def kind(text: str) -> str:
        """The kind of a message: its text with the numbers taken out (stamps, counts)."""
        return re.sub(r'[-+0-9.e]+', '#', text)

    def log(self, logger, key: str, text: str, level: str = 'error') -> None:
        """Log ``text`` at ``level`` unless the same ``key`` was logged in the last second (unlike
        rclpy's per-call-site throttle, different problems from one place all get through)."""
        now = time.monotonic()
        if now - self._last_report.get(key, -math.inf) >= 1.0:
            self._last_report[key] = now
            # One call site per severity: rclpy refuses a severity change at one call site.
            if level == 'error':
                logger.error(text)
            elif level == 'warning':
                logger.warning(text)
            else:
                logger.info(text)

    def done(self, started: float) -> None:
        """Count a processed message whose work began at ``time.perf_counter()`` = ``started``."""
        self.processed += 1
        self._latency.append(time.perf_counter() - started)
        self._last_input = now = self.clock()
        self._stamps.append(now)

    def condition(self, key: str, text: str | None, level: bytes = DiagnosticStatus.WARN) -> None:
        """Set (``text``) or clear (None) a standing problem ``key``, reported until cleared."""
        if text is None:
            self._conditions.pop(key, None)
        else:
            self._conditions[key] = (level, text)

    def expected_period(self) -> float | None:
        """Median interval between the recent processed messages [s]; None before two."""
        if len(self._stamps) < 2:
            return None
        recent = list(self._stamps)[-self.PERIOD_SAMPLES - 1:]
        return statistics.median(b - a for a, b in zip(recent, recent[1:]))

    def rate(self, now: float | None = None) -> float:
        """Processed messages per second over the recent window ending ``now`` (module docstring)."""
        now = self.clock() if now is None else now
        period = self.expected_period()
        if period is None:
            return 0.0
        window = max(self.RATE_WINDOW, self.RATE_WINDOW_PERIODS * period)
        inside = [t for t in self._stamps if t > now - window]
        if len(inside) < 2:
            return 0.0
        # Exact while input comes (last interval not yet overdue), then decaying with the silence.
        span = max(inside[-1] - inside[0], now - period - inside[0])
        return (len(inside) - 1) / span if span > 0 else 0.0

    def silence(self, now: float | None = None) -> float | None:
        """Seconds since the last input (processed or dropped); None before any."""
        if self._last_input is None:
            return None
        return (self.clock() if now is None else now) - self._last_input

    def stale_after(self) -> float:
        """Silence [s] after which the input counts as stopped (module docstring)."""
        period = self.expected_period()
        return max(STALE_PERIODS * (self.UNKNOWN_PERIOD if period is None else period), self.STALE_MIN)

    def array(self, stamp, now: float | None = None) -> DiagnosticArray:
        """The report; ``stamp`` is a builtin_interfaces/Time for the header. Starts a new period for
        the count of recent drops."""
        now = self.clock() if now is None else now
        status = DiagnosticStatus(name=self.name, hardware_id=self.hardware_id)
        findings = sorted(self._conditions.values(), key=lambda c: c[0], reverse=True)
        silence = self.silence(now)
        if self.idle is not None:
            findings.append((DiagnosticStatus.OK, self.idle))
        elif silence is None:
            findings.append((DiagnosticStatus.STALE, f'no {self.what} yet'))
        elif silence > self.stale_after():
            period = self.expected_period()
            expected = f'expected every {period:.3g} s' if period is not None else 'no period known yet'
            findings.append((DiagnosticStatus.WARN, f'no {self.what} for {silence:.1f} s ({expected})'))
        if self._recent_drops:
            findings.append((DiagnosticStatus.WARN, f'{self._recent_drops} messages dropped since the last report'))
        self._recent_drops = 0
        if findings:
            status.level = max(level for level, _ in findings)
            status.message = '; '.join(text for _, text in findings)
        else:
            status.level, status.message = DiagnosticStatus.OK, 'ok'
        period = self.expected_period()
        lat = sorted(self._latency)
        kv = {'processed': str(self.processed), 'rate_hz': f'{self.rate(now):.2f}',
              'expected_period_s': f'{period:.4g}' if period is not None else 'nan',
              'last_input_age_s': f'{silence:.3f}' if silence is not None else 'nan',
              'latency_median_ms': f'{1e3 * lat[len(lat) // 2]:.3f}' if lat else 'nan',
              'latency_max_ms': f'{1e3 * lat[-1]:.3f}' if lat else 'nan'}
        kv.update({f'dropped_{k}': str(v) for k, v in sorted(self.dropped.items())})
        kv.update(self.status)
        kv.update(self.values)
        kv.update({f'subscribers {topic}': str(n) for topic, n in sorted(self.listeners.items())})
        status.values = [KeyValue(key=k, value=v) for k, v in kv.items()]
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = stamp
        return arr


class SequenceGaps:
    """Messages a subscription never got, from gaps in its publisher's sequence numbers.

    rmw_fastrtps_cpp (the package's middleware) numbers every message a publisher writes
    (``publication_sequence_number`` in the message info rclpy hands a two-argument callback); a
    message that left a full queue before the callback took it (the reader's keep-last history, or
    the writer's history while a reliable reader lags), or that best effort lost on the way, leaves a
    gap. rmw_cyclonedds_cpp does not fill the number (rclpy gives None): nothing is counted there, and
    :attr:`supported` says so. rclpy's message info carries no publisher id, so the numbers are only
    read while exactly one publisher is matched; with several, their numbers interleave and gaps
    are not counted. A number at or below the last one is a new publisher (a restart): no gap.
    Losses before the first message read are not counted either: the numbers before it may have
    been written before this subscription matched.
    """

    def __init__(self) -> None:
        self.last: int | None = None
        self.supported: bool | None = None   # None until the first message says

    def lost(self, sequence: int | None, publishers: int) -> int:
        """Messages lost before the one numbered ``sequence``, while ``publishers`` are matched."""
        if sequence is None:
            self.supported, self.last = False, None
            return 0
        self.supported = True
        if publishers != 1 or self.last is None or sequence <= self.last:
            self.last = sequence if publishers == 1 else None
            return 0
        gap, self.last = sequence - self.last - 1, sequence
        return gap

"""``/diagnostics`` for the package's processing nodes: rates, latency, counts, drops."""
from __future__ import annotations

import math
import re
import time
from collections import deque

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

__all__ = ['StageDiagnostics']


class StageDiagnostics:
    """Counts inputs, outputs and drops (by reason) and times processing; builds a DiagnosticArray.

    Level: WARN when messages were dropped in the last report period, STALE before any input,
    OK otherwise.
    """

    def __init__(self, name: str, hardware_id: str = 'sonar') -> None:
        self.name = name
        self.hardware_id = hardware_id
        self.processed = 0
        self.dropped: dict[str, int] = {}
        self._recent_drops = 0
        self._latency: deque[float] = deque(maxlen=200)
        self._stamps: deque[float] = deque(maxlen=200)
        self.values: dict[str, str] = {}
        self.listeners: dict[str, int] = {}
        self._last_report: dict[str, float] = {}

    def drop(self, reason: str) -> None:
        """Count a dropped message under a short reason key."""
        self.dropped[reason] = self.dropped.get(reason, 0) + 1
        self._recent_drops += 1

    def report(self, logger, reason: str, text: str, level: str = 'error') -> None:
        """Count a dropped message and log why: each kind of problem at once, then at most once a
        second (a sensor sending bad data all the time must not flood the log, nor hide a new fault)."""
        self.drop(reason)
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
        now = time.perf_counter()
        self._latency.append(now - started)
        self._stamps.append(now)

    def array(self, stamp) -> DiagnosticArray:
        """The report; ``stamp`` is a builtin_interfaces/Time for the header."""
        status = DiagnosticStatus(name=self.name, hardware_id=self.hardware_id)
        if self.processed == 0:
            status.level, status.message = DiagnosticStatus.STALE, 'no input yet'
        elif self._recent_drops:
            status.level = DiagnosticStatus.WARN
            status.message = f'{self._recent_drops} messages dropped since the last report'
        else:
            status.level, status.message = DiagnosticStatus.OK, 'ok'
        self._recent_drops = 0
        rate = 0.0
        if len(self._stamps) > 1 and self._stamps[-1] > self._stamps[0]:
            rate = (len(self._stamps) - 1) / (self._stamps[-1] - self._stamps[0])
        lat = sorted(self._latency)
        kv = {'processed': str(self.processed), 'rate_hz': f'{rate:.2f}',
              'latency_median_ms': f'{1e3 * lat[len(lat) // 2]:.3f}' if lat else 'nan',
              'latency_max_ms': f'{1e3 * lat[-1]:.3f}' if lat else 'nan'}
        kv.update({f'dropped_{k}': str(v) for k, v in sorted(self.dropped.items())})
        kv.update(self.values)
        kv.update({f'subscribers {topic}': str(n) for topic, n in sorted(self.listeners.items())})
        status.values = [KeyValue(key=k, value=v) for k, v in kv.items()]
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = stamp
        return arr

"""The one time rule of the package's nodes: what a stamp that is not newer than the last means.

* a newer stamp is processed;
* a repeated stamp, or one at most ``jump_reset`` seconds older than the last, is a late or
  duplicated message: dropped and counted, the node's state untouched;
* a stamp more than ``jump_reset`` seconds older is a new recording (a looping bag, a restarted
  driver): the node restarts its state and processes it.

A node asks :meth:`TimeGuard.check` before processing and calls :meth:`TimeGuard.accept` only once
the message was processed, so a dropped message never moves the guard.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ['TimeGuard', 'NEW', 'LATE', 'RESET']

NEW, LATE, RESET = 'new', 'late', 'reset'


@dataclass
class TimeGuard:
    """Classifies stamps against the last accepted one (see the module docstring)."""

    last_ns: int | None = None

    def check(self, stamp_ns: int, jump_reset: float) -> tuple[str, float]:
        """``(verdict, seconds back)``: verdict NEW, LATE (drop) or RESET (restart, then process)."""
        if self.last_ns is None or stamp_ns > self.last_ns:
            return NEW, 0.0
        back = (self.last_ns - stamp_ns) / 1e9
        if stamp_ns == self.last_ns or back <= jump_reset:
            return LATE, back
        return RESET, back

    def accept(self, stamp_ns: int) -> None:
        """Note a processed stamp."""
        self.last_ns = stamp_ns

    def reset(self) -> None:
        """Forget the last stamp (after a restart)."""
        self.last_ns = None

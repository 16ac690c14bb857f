"""Time in the core: objects that keep state over time refuse a stamp older than their last one.

A tracker or an image builder cannot tell a late message from a new recording (a looping bag, a
restarted driver); its caller can. So the core raises :class:`TimeWentBack` before it changes
anything, and the caller decides: the ROS nodes drop a small step back and restart on a large one
(:mod:`sonar_tracking.ros.timeline`), ``sonar_eval track`` restarts its tracker (a file of several
recordings one after the other). An equal stamp is not a step back; each core says what it does
with one.
"""
from __future__ import annotations

__all__ = ['TimeWentBack', 'check_forward']


class TimeWentBack(ValueError):
    """A stamp [s] before the previous one; nothing was changed. ``back`` is how far, in seconds."""

    def __init__(self, what: str, stamp: float, last: float) -> None:
        self.stamp, self.last = float(stamp), float(last)
        super().__init__(f'{what} at {self.stamp:.6f} s is {self.back:.6g} s before the previous one '
                         f'({self.last:.6f} s); reset() to start again from it')

    @property
    def back(self) -> float:
        return self.last - self.stamp


def check_forward(what: str, stamp: float, last: float | None) -> None:
    """Raise :class:`TimeWentBack` when ``stamp`` is before ``last`` (None: nothing processed yet)."""
    if last is not None and stamp < last:
        raise TimeWentBack(what, stamp, last)

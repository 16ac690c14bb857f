"""Planar sensor poses over time, for placing a sector taken at a given stamp.

Odometry arrives at its own rate; :class:`PoseBuffer` keeps the recent poses and interpolates
position linearly and yaw along the shorter arc. Outside the buffered span the nearest pose is
used if it is within ``max_extrapolation`` seconds, otherwise there is no pose (the caller falls
back to its static pose and says so).

One message must never outlive its neighbours. A pose stamped more than ``max_gap`` seconds after
the newest buffered one, or more than ``max_back`` seconds before it (a clock gone wrong, a stale
publisher, or a real jump: an odometry outage, a new recording), is *held*, not buffered: the next
pose within ``max_gap`` of the held one confirms the jump (both are buffered; a jump back replaces
the buffer: a new recording), a pose that continues the buffered stream discards it, and so does a
later held pose. Data stamped near a held pose also confirms it (:meth:`PoseBuffer.pose_at`): the
first sector of a new recording may arrive before its second odometry message.
"""
from __future__ import annotations

import bisect
import math
from typing import cast

__all__ = ['PoseBuffer', 'MAX_POSITION', 'ADDED', 'HELD', 'JUMPED']

Pose = tuple[float, float, float]

#: Largest |x| or |y| of a pose [m]: 10,000 km (UTM northings stay below it). Beyond is no place on Earth.
MAX_POSITION = 1e7

ADDED, HELD, JUMPED = 'added', 'held', 'jumped'


class PoseBuffer:
    """Time-ordered ``(t, x, y, yaw)``; ``pose_at(t)`` interpolates; jumps are held (module docstring)."""

    def __init__(self, max_age: float = 30.0, max_extrapolation: float = 2.0, max_gap: float = 10.0,
                 max_back: float = 3.0) -> None:
        self.max_age = max_age
        self.max_extrapolation = max_extrapolation
        self.max_gap = max_gap
        self.max_back = max_back
        self._t: list[float] = []
        self._p: list[Pose] = []
        self.held: tuple[float, float, float, float] | None = None
        self.discarded = 0
        self._restarted = False

    def __len__(self) -> int:
        return len(self._t)

    @property
    def newest(self) -> float:
        """Stamp of the newest buffered pose (-inf when empty); a held pose does not count."""
        return self._t[-1] if self._t else -math.inf

    def clear(self) -> None:
        """Forget the buffered poses (a held pose stays: it may be the first of a new recording)."""
        self._t.clear()
        self._p.clear()

    def restart(self) -> None:
        """The data went back in time (a new recording). The next :meth:`pose_at` forgets the buffered
        poses unless they lie around its stamp (the odometry went back on its own already)."""
        self._restarted = True

    def add(self, t: float, x: float, y: float, yaw: float) -> str:
        """Take a pose: ADDED to the buffer, HELD (a jump of more than ``max_gap``), or JUMPED (a held
        pose confirmed; both buffered). A held pose that this one discards is counted in
        :attr:`discarded`."""
        if not self._t or self._near_stream(t):
            if self.held is not None:
                self.held = None
                self.discarded += 1
            self._insert(t, x, y, yaw)
            return ADDED
        if self.held is not None and abs(t - self.held[0]) <= self.max_gap:
            self._confirm_held()
            self._insert(t, x, y, yaw)
            return JUMPED
        if self.held is not None:
            self.discarded += 1
        self.held = (t, x, y, yaw)
        return HELD

    def _confirm_held(self) -> None:
        """Buffer the held pose: its jump is confirmed (a jump back replaces the buffer: a new recording)."""
        held = cast(tuple[float, float, float, float], self.held)
        self.held = None
        if self._t and held[0] < self._t[0]:
            self.clear()
        self._insert(*held)

    def _near_stream(self, t: float) -> bool:
        return self._t[-1] - self.max_back <= t <= self._t[-1] + self.max_gap

    def _insert(self, t: float, x: float, y: float, yaw: float) -> None:
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            self._p[i] = (x, y, yaw)
        else:
            self._t.insert(i, t)
            self._p.insert(i, (x, y, yaw))
        cut = bisect.bisect_left(self._t, self._t[-1] - self.max_age)
        if cut:
            del self._t[:cut], self._p[:cut]

    def pose_at(self, t: float) -> Pose | None:
        """Interpolated pose at ``t``, or None when no pose is near enough. A held pose within
        ``max_extrapolation`` of ``t``, where the buffer has none, is confirmed by it first."""
        if self._restarted:
            self._restarted = False
            if self._t and not self._near_stream(t):
                self.clear()
        if self.held is not None and abs(self.held[0] - t) <= self.max_extrapolation and (
                not self._t or not self._near_stream(t)):
            self._confirm_held()
        if not self._t:
            return None
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            return self._p[i]
        if i == 0 or i == len(self._t):
            j = 0 if i == 0 else len(self._t) - 1
            return self._p[j] if abs(self._t[j] - t) <= self.max_extrapolation else None
        t0, t1 = self._t[i - 1], self._t[i]
        (x0, y0, a0), (x1, y1, a1) = self._p[i - 1], self._p[i]
        w = (t - t0) / (t1 - t0)
        da = math.remainder(a1 - a0, 2 * math.pi)
        return (x0 + w * (x1 - x0), y0 + w * (y1 - y0), math.remainder(a0 + w * da, 2 * math.pi))

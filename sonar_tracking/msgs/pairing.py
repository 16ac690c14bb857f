"""Pairing messages that belong together by their stamp (a sector's image and geometry, an FLS frame's
image, image_info and regions).

A producer publishes the parts of one stamp together and stamps in increasing order, so once a stamp
is complete, older incomplete stamps can never complete and are given up; so are the oldest stamps
once more than ``max_pending`` wait, and a late part of a stamp given up for that reason is dropped
at once (it could only push out a stamp that can still complete). Given-up stamps are reported by
:meth:`pop_dropped`.
"""
from __future__ import annotations

from collections import OrderedDict
from typing import Any

__all__ = ['StampPairer']


class StampPairer:
    """Collects the ``parts`` of each stamp; ``add`` returns ``{part: msg}`` once a stamp is complete."""

    def __init__(self, parts: tuple[str, ...], max_pending: int = 16) -> None:
        if max_pending < 1:
            raise ValueError('max_pending must be >= 1')
        self.parts = tuple(parts)
        self.max_pending = max_pending
        self._pending: dict[int, dict[str, Any]] = {}
        self._evicted: OrderedDict[int, None] = OrderedDict()   # recent stamps pushed out by max_pending
        self._dropped: list[tuple[int, tuple[str, ...]]] = []

    def add(self, part: str, stamp_ns: int, msg: Any) -> dict[str, Any] | None:
        """Offer one part of stamp ``stamp_ns``; a part offered twice for one stamp replaces the first
        (the first is reported as dropped)."""
        if part not in self.parts:
            raise ValueError(f'unknown part {part!r}; one of {list(self.parts)}')
        if stamp_ns in self._evicted:
            self._dropped.append((stamp_ns, (part,)))
            return None
        frame = self._pending.setdefault(stamp_ns, {})
        if part in frame:
            self._dropped.append((stamp_ns, (part,)))  # the earlier copy is replaced
        frame[part] = msg
        if len(frame) == len(self.parts):
            del self._pending[stamp_ns]
            for old in [s for s in self._pending if s < stamp_ns]:
                self._dropped.append((old, tuple(sorted(self._pending.pop(old)))))
            return frame
        while len(self._pending) > self.max_pending:
            old = min(self._pending)
            self._dropped.append((old, tuple(sorted(self._pending.pop(old)))))
            self._evicted[old] = None
            while len(self._evicted) > 4 * self.max_pending:
                self._evicted.popitem(last=False)
        return None

    def pop_dropped(self) -> list[tuple[int, tuple[str, ...]]]:
        """``[(stamp_ns, parts that were there), ...]`` given up since the last call."""
        out, self._dropped = self._dropped, []
        return out

    def missing(self, present: tuple[str, ...]) -> tuple[str, ...]:
        """The parts not in ``present``."""
        return tuple(p for p in self.parts if p not in present)

    def restart(self, last_ns: int) -> None:
        """Time went back: a new recording starts before ``last_ns``, the newest stamp taken of the old one.

        The old recording's pending stamps (after ``last_ns``; older ones were given up when it
        completed) can never complete and are given up; the stamps pushed out by ``max_pending`` are
        forgotten, since the new recording may use the same stamps (a looping bag). Parts of the new
        recording that arrived before the stamp that showed the jump are kept: two topics are not
        delivered in step, so some of them often do.
        """
        for old in [s for s in self._pending if s > last_ns]:
            self._dropped.append((old, tuple(sorted(self._pending.pop(old)))))
        self._evicted.clear()

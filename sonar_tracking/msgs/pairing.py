"""Pairing messages that belong together by their stamp (a sector's image and geometry, an FLS frame's
image, image_info and regions).

A producer publishes the parts of one stamp together and stamps in increasing order, and each topic is
delivered in order, so once a stamp is complete, older incomplete stamps can never complete: their
missing parts were lost before they reached the pairer. Those stamps are given up as ``unpaired``
(and so are a restart's old stamps, :meth:`StampPairer.restart`).

At most ``max_pending`` stamps wait; when one more arrives, the oldest is given up as ``evicted``,
and a part of an evicted stamp that arrives later is dropped at once, also as ``evicted`` (it could
only push out a stamp that can still complete). Under a burst, one topic can run ahead of the other
by as many messages as a subscription queue holds, so ``max_pending`` should be at least the input
queue depth: then a partner still on its way is never evicted. A part offered twice for one stamp
replaces the first, which is given up as ``duplicate``.

Given-up parts are reported by :meth:`StampPairer.pop_dropped_with_reasons` (``(stamp, parts,
reason)``) or :meth:`StampPairer.pop_dropped` (``(stamp, parts)``); every part offered is either in a
completed frame, waiting, or reported exactly once.
"""
from __future__ import annotations

from collections import OrderedDict
from typing import Any

__all__ = ['StampPairer', 'UNPAIRED', 'EVICTED', 'DUPLICATE', 'GIVEN_UP']

#: The partner never came (a newer stamp completed first, or time restarted).
UNPAIRED = 'unpaired'
#: Pushed out because more than ``max_pending`` stamps waited, or a late part of such a stamp.
EVICTED = 'evicted'
#: Replaced by a second copy of the same part of the same stamp.
DUPLICATE = 'duplicate'
#: What each reason means for a part given up, for logs.
GIVEN_UP = {UNPAIRED: 'never got its partner', EVICTED: 'was pushed out of the pairing queue (max_pending stamps '
            'waited) before its partner came', DUPLICATE: 'came twice (the later copy is kept)'}


class StampPairer:
    """Collects the ``parts`` of each stamp; ``add`` returns ``{part: msg}`` once a stamp is complete."""

    def __init__(self, parts: tuple[str, ...], max_pending: int = 16) -> None:
        if max_pending < 1:
            raise ValueError('max_pending must be >= 1')
        self.parts = tuple(parts)
        self.max_pending = max_pending
        self._pending: dict[int, dict[str, Any]] = {}
        self._evicted: OrderedDict[int, None] = OrderedDict()   # recent stamps pushed out by max_pending
        self._dropped: list[tuple[int, tuple[str, ...], str]] = []

    def add(self, part: str, stamp_ns: int, msg: Any) -> dict[str, Any] | None:
        """Offer one part of stamp ``stamp_ns``; a part offered twice for one stamp replaces the first
        (the first is reported as dropped)."""
        if part not in self.parts:
            raise ValueError(f'unknown part {part!r}; one of {list(self.parts)}')
        if stamp_ns in self._evicted:
            self._dropped.append((stamp_ns, (part,), EVICTED))
            return None
        frame = self._pending.setdefault(stamp_ns, {})
        if part in frame:
            self._dropped.append((stamp_ns, (part,), DUPLICATE))  # the earlier copy is replaced
        frame[part] = msg
        if len(frame) == len(self.parts):
            del self._pending[stamp_ns]
            for old in [s for s in self._pending if s < stamp_ns]:
                self._dropped.append((old, tuple(sorted(self._pending.pop(old))), UNPAIRED))
            return frame
        while len(self._pending) > self.max_pending:
            old = min(self._pending)
            self._dropped.append((old, tuple(sorted(self._pending.pop(old))), EVICTED))
            self._evicted[old] = None
            while len(self._evicted) > 4 * self.max_pending:
                self._evicted.popitem(last=False)
        return None

    def pop_dropped_with_reasons(self) -> list[tuple[int, tuple[str, ...], str]]:
        """``[(stamp_ns, parts that were there, reason), ...]`` given up since the last call; the
        reason is :data:`UNPAIRED`, :data:`EVICTED` or :data:`DUPLICATE` (module docstring)."""
        out, self._dropped = self._dropped, []
        return out

    def pop_dropped(self) -> list[tuple[int, tuple[str, ...]]]:
        """``[(stamp_ns, parts that were there), ...]`` given up since the last call."""
        return [(stamp, parts) for stamp, parts, _ in self.pop_dropped_with_reasons()]

    @property
    def pending_parts(self) -> int:
        """How many parts wait for the rest of their stamp."""
        return sum(len(frame) for frame in self._pending.values())

    def missing(self, present: tuple[str, ...]) -> tuple[str, ...]:
        """The parts not in ``present``."""
        return tuple(p for p in self.parts if p not in present)

    def restart(self, last_ns: int) -> None:
        """Time went back: a new recording starts before ``last_ns``, the newest stamp taken of the old one.

        The old recording's pending stamps (after ``last_ns``; older ones were given up when it
        completed) can never complete and are given up as unpaired; the stamps pushed out by
        ``max_pending`` are forgotten, since the new recording may use the same stamps (a looping
        bag). Parts of the new recording that arrived before the stamp that showed the jump are
        kept: two topics are not delivered in step, so some of them often do.
        """
        for old in [s for s in self._pending if s > last_ns]:
            self._dropped.append((old, tuple(sorted(self._pending.pop(old))), UNPAIRED))
        self._evicted.clear()

"""Holding a publisher back until its readers are there (``seaking_sim wait_for_subscribers``).

:class:`SubscriberGate` opens once the ``key`` publishers each have ``count`` subscribers and then,
for ``settle`` seconds without a change, every subscriber the graph knows of on ``all`` the
publishers' topics is connected to them: discovery of the other processes settles first, so nobody
misses the start of a run at full speed. Three seconds later the second condition is given up (a
subscriber of incompatible QoS never connects).
"""
from __future__ import annotations

import time
from collections.abc import Sequence

__all__ = ['SubscriberGate']


class SubscriberGate:
    """``ready()`` is True once the readers are there (module docstring); ``count`` 0 opens at once."""

    GIVE_UP = 3.0

    def __init__(self, node, key: Sequence, every: Sequence, count: int, settle: float) -> None:
        self.node, self.key, self.every, self.count, self.settle = node, tuple(key), tuple(every), count, settle
        self._matched_since: float | None = None
        self._connected_since: float | None = None

    def ready(self) -> bool:
        if self.count == 0:
            return True
        now = time.monotonic()
        if min(p.get_subscription_count() for p in self.key) < self.count:
            self._matched_since = self._connected_since = None
            return False
        self._matched_since = self._matched_since or now
        if all(p.get_subscription_count() >= self.node.count_subscribers(p.topic_name) for p in self.every):
            self._connected_since = self._connected_since or now
        else:
            self._connected_since = None
        settled = self._connected_since is not None and now - self._connected_since >= self.settle
        return settled or now - self._matched_since > self.settle + self.GIVE_UP

    def describe(self) -> str:
        """Subscriber counts of every publisher, for the log."""
        return ', '.join(f'{p.topic_name} {p.get_subscription_count()}' for p in self.every)

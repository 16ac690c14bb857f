"""Whether a node is looking yet: its state on a latched topic, so "nothing found" differs from "not looking yet".

Every processing node (:class:`~sonar_tracking.ros.node.SonarNode`) publishes its state on
``~/status`` (``/NAMESPACE/NODE/status``; ``std_msgs/String``; reliable, transient local, depth 1,
so a reader that comes late gets the current state and never an old one) whenever it changes, and
shows it in ``/diagnostics`` (value ``state``, and the message while learning). The text is one
JSON object::

    {"node": "/active_detector", "state": "learning", "seconds_left": 6.5,
     "detail": "learning the structure background: no output for seconds_left more seconds of input"}

* ``starting``: the node is being built (parameters, compiled kernels: the warm-up of
  :mod:`sonar_tracking.ros.warmup`); it takes no input yet, and input sent now may be lost;
* ``learning``: the node takes input but outputs nothing yet: the structure background learns
  (``structure.warmup``) for ``seconds_left`` more seconds of input, by the input's stamps (a
  replay at twice the speed learns in half the wall time). It starts at ``structure.min_echo_time``
  before the first input and again after a restart (a jump back in time, a reset, a changed
  ``structure`` setting). While learning the value is published again each time the whole seconds
  left change;
* ``ready``: the node takes input and outputs what it finds.

A node that learns nothing (no structure rejection, or ``structure.warmup: false``) goes from
``starting`` straight to ``ready``. Tools that start input (``bag_replay --wait-for`` and
``--wait-ready``, ``sonar_stack --replay``) wait until no node of the graph says ``starting``
(:class:`StatusWatch`); ``sonar_stack`` publishes the same record for the whole stack on
``sonar_stack/status`` in its namespace, with ``nodes`` mapping each of its nodes to its state, and
the least ready state of them as its own.
"""
from __future__ import annotations

import json
import math
from collections.abc import Iterable
from typing import Any

from std_msgs.msg import String

from sonar_tracking.core.structure import StructureConfig, WarmUp
from sonar_tracking.ros.qos import latest_profile

__all__ = ['STARTING', 'LEARNING', 'READY', 'STATES', 'STATUS_TOPIC', 'NodeStatus', 'StatusWatch',
           'warmup_left', 'parse_status', 'least_ready', 'status_topic']

STARTING, LEARNING, READY = 'starting', 'learning', 'ready'
#: The states, least ready first.
STATES = (STARTING, LEARNING, READY)
#: The status topic of a node, private to it.
STATUS_TOPIC = '~/status'


def status_topic(node_fqn: str) -> str:
    """The status topic of the node of fully qualified name ``node_fqn`` (``/ns/name``)."""
    return node_fqn.rstrip('/') + '/status'


def warmup_left(warmup: WarmUp, config: StructureConfig, t: float | None) -> float:
    """Seconds of input (by stamps) before ``warmup`` stops holding output back, with the last input
    at ``t`` [s] (None: no input since the start or the last reset); 0 when nothing is held."""
    probe = WarmUp()                     # a copy: asking ``warmup`` itself would start its clock
    probe.start = warmup.start
    if t is None or warmup.start is None:
        return float(config.min_echo_time) if probe.holding(0.0, config) else 0.0
    if not probe.holding(t, config):
        return 0.0
    return max(0.0, float(config.min_echo_time) - (t - float(warmup.start)))


def least_ready(states: Iterable[str | None]) -> str:
    """The least ready of ``states`` (None, not heard yet, counts as starting); ready when there are none."""
    rank = [STATES.index(s) if s in STATES else 0 for s in states]
    return STATES[min(rank)] if rank else READY


def parse_status(text: str) -> dict | None:
    """The record of a status message, or None when ``text`` is not one (another node's ``status`` topic)."""
    try:
        record = json.loads(text)
    except ValueError:
        return None
    if not isinstance(record, dict) or record.get('state') not in STATES:
        return None
    return record


class NodeStatus:
    """A node's state, published on ``~/status`` when it changes (module docstring)."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.pub = node.create_publisher(String, STATUS_TOPIC, latest_profile())
        self.state: str | None = None
        self.seconds_left = 0.0
        self.detail = ''
        self._shown: tuple | None = None

    def set(self, state: str, seconds_left: float = 0.0, detail: str = '', **extra: Any) -> bool:
        """Set the state; publishes and returns True when it changed (while learning: also when the
        whole seconds left changed)."""
        if state not in STATES:
            raise ValueError(f'state {state!r} is not one of {STATES}')
        seconds_left = max(0.0, float(seconds_left)) if state == LEARNING else 0.0
        shown = (state, math.ceil(seconds_left), detail, json.dumps(extra, sort_keys=True))
        self.state, self.seconds_left, self.detail = state, seconds_left, detail
        if shown == self._shown:
            return False
        self._shown = shown
        record = {'node': self.node.get_fully_qualified_name(), 'state': state,
                  'seconds_left': round(seconds_left, 3), 'detail': detail, **extra}
        self.pub.publish(String(data=json.dumps(record)))
        return True


class StatusWatch:
    """Follows the status topics of nodes (``names``: fully qualified names), or with ``names`` None
    of every node of the graph that publishes one, found by :meth:`discover`. The caller spins
    ``node``. A topic whose messages are not status records (another package's ``status``) is ignored."""

    def __init__(self, node: Any, names: Iterable[str] | None = None) -> None:
        self.node = node
        self.auto = names is None
        self.records: dict[str, dict | None] = {}
        self.foreign: set[str] = set()
        self._subs: dict[str, Any] = {}
        for name in names or ():
            self.follow(name)

    def follow(self, name: str) -> None:
        """Follow the status of node ``name`` (fully qualified)."""
        if name in self._subs:
            return
        self.records[name] = None

        def heard(msg: String, name: str = name) -> None:
            record = parse_status(msg.data)
            if record is None:
                self.foreign.add(name)
            else:
                self.foreign.discard(name)
                self.records[name] = record
        self._subs[name] = self.node.create_subscription(String, status_topic(name), heard, latest_profile())

    def discover(self) -> None:
        """Follow every node of the graph that publishes a ``std_msgs/String`` on its ``status`` topic."""
        for name, ns in self.node.get_node_names_and_namespaces():
            fqn = (ns.rstrip('/') + '/' + name) if ns != '/' else '/' + name
            if fqn in self._subs or fqn == self.node.get_fully_qualified_name():
                continue
            try:
                topics = self.node.get_publisher_names_and_types_by_node(name, ns)
            except Exception:  # noqa: BLE001 - the node left the graph meanwhile
                continue
            if any(t == status_topic(fqn) and 'std_msgs/msg/String' in types for t, types in topics):
                self.follow(fqn)

    def states(self) -> dict[str, str | None]:
        """Each followed node's state (None: not heard yet), foreign topics left out."""
        return {name: (r or {}).get('state') for name, r in self.records.items() if name not in self.foreign}

    def state(self) -> str:
        """The least ready state of the followed nodes (:func:`least_ready`)."""
        return least_ready(self.states().values())

    def waiting(self) -> list[str]:
        """The followed nodes that still say ``starting`` (or were not heard yet), as ``name (state)``."""
        return [f'{name} ({state or "not heard yet"})' for name, state in sorted(self.states().items())
                if state not in (LEARNING, READY)]

    def close(self) -> None:
        for sub in self._subs.values():
            self.node.destroy_subscription(sub)
        self._subs.clear()

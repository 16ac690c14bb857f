"""The pace, the stamps and the ``/clock`` of a source that publishes simulated time (``seaking_sim``).

``rate`` 1 publishes in real time, 2 twice as fast, 0 as fast as the readers take it. The stamps
are the wall clock at which a message is due (``wall``), or simulated time from an offset
(``sim``). The processing nodes work on the stamps of their input alone, so neither needs ``/clock``.

``/clock`` (:class:`SimClock`) is published only on request (``publish_clock``), and by one node of
a domain at most:

* **What it says**: the stamps' clock at the simulated time now (:meth:`Pacer.sim_now`; at ``rate``
  0, simulated time moves with the sectors). Before a message is published, ``/clock`` reaches its
  stamp, so no published stamp is ever ahead of ``/clock``; in between, a timer moves it along in
  steps of at most ``clock_period`` (10 ms) of simulated time. It never goes back: a value not
  above the last one published is not published (a re-anchored pace holds it until time catches up).
* **Only one publisher**: a new clock first listens on ``/clock`` until, for ``SimClock.CLAIM``
  seconds, the graph has shown other nodes with their publishers and kept its nodes and endpoints
  (discovery of the other processes has begun and settled) and it has been connected to every
  other ``/clock`` publisher; ``SimClock.CLAIM_MAX`` seconds at most (a node alone in its domain
  waits that long). It refuses, with one error naming the other node and a WARN in the
  diagnostics, when it hears another node's ``/clock``, or when, at the end of the claim, the graph
  shows another ``/clock`` publisher whose GID sorts lower than its own (two started together: the
  lowest GID keeps it). A publishing clock repeats its value every ``SimClock.HEARTBEAT`` seconds,
  so a newcomer always hears it. If it hears another node's ``/clock`` nonetheless (discovery
  slower than the claim), the one of lower GID keeps publishing and the other stops at once; a
  publisher that goes on for ``SimClock.YIELD_WAIT`` seconds does not follow this rule (another
  tool) and is left the clock. A refused clock stays off and leaves the graph.
"""
from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from sonar_tracking.core.config import Config, setting
from sonar_tracking.msgs.stamps import ns_to_stamp, stamp_to_ns
from sonar_tracking.ros.qos import CLOCK_TOPIC

__all__ = ['PacingConfig', 'Pacer', 'SimClock']


@dataclass(frozen=True)
class PacingConfig(Config):
    """How a source of simulated time publishes: pace, stamps, clock, and when it starts and ends."""

    rate: float = setting(1.0, 'pace: 1 = real time, 2 = twice as fast, 0 = as fast as subscribers take it',
                          low=0.0, high=1e4)
    stamps: str = setting('auto', 'clock of the stamps: wall, sim (simulated time from stamp_offset), or auto (wall '
                          'when starting at rate 1, else sim)', choices=('auto', 'wall', 'sim'), read_only=True)
    stamp_offset: float = setting(0.0, 'stamp of the scenario start with sim stamps', unit='s', low=0.0, high=4e9,
                                  read_only=True)
    publish_clock: bool = setting(False, 'publish /clock (the stamps\' clock, for use_sim_time nodes), unless '
                                  'another node publishes it already', read_only=True)
    clock_period: float = setting(0.01, 'with publish_clock: largest step of /clock', unit='s of simulated time',
                                  low=0.001, high=0.01, read_only=True)
    shutdown_when_done: bool = setting(False, 'exit once the scenario has ended', read_only=True)
    wait_for_subscribers: int = setting(0, 'start once /sonar/sector and /sonar/sector_info have this many '
                                        'subscribers and every subscriber in the graph is connected (0 = at once)',
                                        low=0, high=1000, read_only=True)
    start_settle_time: float = setting(1.0, 'with wait_for_subscribers: how long the graph must stay connected '
                                       'before the start (3.5 s for subscribers of tools that announce every 3 s)',
                                       unit='s', low=0.0, high=60.0, read_only=True)


class Pacer:
    """When each simulated instant is due on the wall clock, and the stamp it carries."""

    def __init__(self, config: PacingConfig, sim_now: float) -> None:
        self.rate, self.stamp_offset = config.rate, config.stamp_offset
        self.wall_stamps = config.stamps == 'wall' or (config.stamps == 'auto' and config.rate == 1.0)
        self.anchor(sim_now)

    def anchor(self, sim_now: float, rate: float | None = None) -> None:
        """Tie simulated time ``sim_now`` to now (at start, while waiting, and when ``rate`` changes)."""
        self.rate = self.rate if rate is None else rate
        self._wall0, self._epoch0_ns, self._sim0 = time.monotonic(), time.time_ns(), sim_now

    def due(self, sim_t: float) -> bool:
        """Whether simulated time ``sim_t`` is due now (always with ``rate`` 0)."""
        return self.rate == 0 or time.monotonic() >= self._wall0 + (sim_t - self._sim0) / self.rate

    def sim_now(self) -> float | None:
        """The simulated time now; None with ``rate`` 0 (simulated time then moves with the sectors)."""
        if self.rate == 0:
            return None
        return self._sim0 + (time.monotonic() - self._wall0) * self.rate

    def stamp_ns(self, sim_t: float) -> int:
        """The stamp of simulated time ``sim_t``: the wall time it is due at, or simulated time."""
        if not self.wall_stamps:
            return int(round((self.stamp_offset + sim_t) * 1e9))
        if self.rate == 0:
            return time.time_ns()
        return self._epoch0_ns + int(round((sim_t - self._sim0) / self.rate * 1e9))


def clock_steps(last_ns: int | None, target_ns: int, period_ns: int, max_steps: int) -> list[int]:
    """The ``/clock`` values from ``last_ns`` (excluded) to ``target_ns``, evenly spaced at most
    ``period_ns`` apart (wider beyond ``max_steps`` steps); empty unless ``target_ns`` is later."""
    if last_ns is None:
        return [target_ns]
    if target_ns <= last_ns:
        return []
    n = min(max(1, math.ceil((target_ns - last_ns) / period_ns)), max_steps)
    return [last_ns + (target_ns - last_ns) * i // n for i in range(1, n + 1)]


class SimClock:
    """``/clock`` of one simulated source, alone in the domain and monotone (module docstring).

    ``advance(ns)`` moves it to ``ns``; ``state`` is ``claiming``, ``publishing`` or ``refused``
    (``reason`` says why); ``on_change()`` hears every change of state.
    """

    CLAIM = 1.0          # s of a settled graph before the first /clock
    CLAIM_MAX = 5.0      # s, longest claim
    CHECK = 0.1          # s between looks at the graph
    HEARTBEAT = 0.1      # s, longest silence while publishing
    YIELD_WAIT = 1.0     # s a publisher of higher GID is given to stop
    FOREIGN_GONE = 0.5   # s without another node's /clock after which it has stopped
    MAX_STEPS = 10000    # values per advance (a pace of more than 10000 steps per tick widens them)
    SENT = 4096          # own recent values kept to tell own messages from another node's

    def __init__(self, node: Any, period: float, on_change: Callable[[], None] | None = None) -> None:
        self.node, self.period_ns, self.on_change = node, max(1, int(round(period * 1e9))), on_change
        before = self._publishers()
        self.pub = node.create_publisher(Clock, CLOCK_TOPIC, 100)
        new = {gid for gid in self._publishers() if gid not in before}
        # The graph lists a local publisher at once; if another appeared in the same instant, ours is
        # unknown and taken as the highest GID: this clock yields to every other.
        self.gid = new.pop() if len(new) == 1 else b'\xff' * 64
        self.state, self.reason = 'claiming', ''
        self.last_ns: int | None = None
        self.target_ns: int | None = None
        self._sent: deque[int] = deque(maxlen=self.SENT)
        self._sent_set: set[int] = set()
        self._foreign_first: float | None = None   # another node's /clock heard since, and last
        self._foreign_last = -math.inf
        self._started = self._last_sent = self._settled_since = time.monotonic()
        self._seen: tuple = ()
        self.sub = node.create_subscription(Clock, CLOCK_TOPIC, self._heard, QoSProfile(
            depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.timer = node.create_timer(self.CHECK, self._check)

    def _publishers(self) -> dict[bytes, str]:
        """GID -> node of every ``/clock`` publisher in the graph."""
        return {bytes(i.endpoint_gid): f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                for i in self.node.get_publishers_info_by_topic(CLOCK_TOPIC)}

    def advance(self, ns: int) -> None:
        """Move ``/clock`` to ``ns`` (steps of at most ``clock_period``); earlier values are ignored."""
        if self.target_ns is None or ns > self.target_ns:
            self.target_ns = ns
        if self.state == 'publishing':
            for value in clock_steps(self.last_ns, ns, self.period_ns, self.MAX_STEPS):
                self._send(value)

    def _send(self, ns: int) -> None:
        if not self._sent or self._sent[-1] != ns:   # a repeated value is kept once
            if len(self._sent) == self._sent.maxlen:
                self._sent_set.discard(self._sent[0])
            self._sent.append(ns)
            self._sent_set.add(ns)
        self.pub.publish(Clock(clock=ns_to_stamp(ns)))
        self.last_ns, self._last_sent = ns, time.monotonic()

    def _heard(self, msg: Any) -> None:
        if stamp_to_ns(msg.clock) not in self._sent_set:
            self._foreign_last = time.monotonic()
            if self._foreign_first is None:
                self._foreign_first = self._foreign_last

    def _check(self) -> None:
        if self.state == 'refused':
            return
        now = time.monotonic()
        others = {gid: name for gid, name in self._publishers().items() if gid != self.gid}
        lower = sorted(name for gid, name in others.items() if gid < self.gid)
        names = ', '.join(sorted(set(others.values()))) or 'a node not in the graph'
        if self.state == 'claiming':
            if self._foreign_first is not None:
                # Its messages can come before the graph lists it: wait for its name (a while at most).
                if others or now - self._started >= self.CLAIM_MAX:
                    self._refuse(f'/clock is already published by {names}')
            elif not (self._settled(now, others) or now - self._started >= self.CLAIM_MAX):
                return
            elif lower:   # decided once settled: a publisher that left meanwhile does not count
                self._refuse(f'/clock is also claimed by {", ".join(lower)}, whose publisher GID sorts lower')
            else:
                self._set('publishing', '')
                if self.target_ns is not None:
                    self._send(self.target_ns)
            return
        if self._foreign_first is not None and now - self._foreign_last > self.FOREIGN_GONE:
            self._foreign_first = None   # the other one stopped
        if self._foreign_first is not None:
            if lower:
                self._refuse(f'/clock is also published by {", ".join(lower)}, whose publisher GID sorts lower')
                return
            if now - self._foreign_first >= self.YIELD_WAIT:
                self._refuse(f'/clock is also published by {names}, which does not stop')
                return
        if self.last_ns is not None and now - self._last_sent >= self.HEARTBEAT:
            self._send(self.last_ns)

    def _settled(self, now: float, others: dict[bytes, str]) -> bool:
        """Whether, for ``CLAIM`` seconds, the graph has shown other nodes, each with its publishers,
        and kept its nodes and endpoints, and this clock has been connected to every other publisher."""
        graph = self._graph()
        # Node names come with the first announcement of a process, its endpoints later: wait for both.
        unknown = len(graph[0]) <= 1 or not all(graph[2])
        if graph != self._seen or unknown or self.sub.get_publisher_count() <= len(others):   # own one counts
            self._seen, self._settled_since = graph, now
        return now - self._settled_since >= self.CLAIM

    def _graph(self) -> tuple[list[tuple[str, str]], list[tuple[str, int, int]], list[bool]]:
        """Nodes; topics with their publisher and subscriber counts; whether each other node shows a publisher."""
        n = self.node
        nodes = sorted(n.get_node_names_and_namespaces())
        topics = [(t, n.count_publishers(t), n.count_subscribers(t)) for t, _ in sorted(n.get_topic_names_and_types())]
        own = (n.get_name(), n.get_namespace())
        shown = []
        for name, ns in nodes:
            if (name, ns) != own:
                try:
                    shown.append(bool(n.get_publisher_names_and_types_by_node(name, ns)))
                except Exception:  # noqa: BLE001 - a node that left between the two calls
                    shown.append(False)
        return nodes, topics, shown

    def _refuse(self, why: str) -> None:
        self.node.get_logger().error(f'{why}: {self.node.get_name()} does not publish /clock (only one node of a '
                                     'domain may; time would go back for every use_sim_time node)')
        # Out of the graph, so the publisher that keeps the clock sees no other.
        self.timer.cancel()
        self.node.destroy_subscription(self.sub)
        self.node.destroy_publisher(self.pub)
        self._set('refused', why)

    def _set(self, state: str, reason: str) -> None:
        self.state, self.reason = state, reason
        if self.on_change is not None:
            self.on_change()

    def describe(self) -> str:
        """The state for diagnostics."""
        return f'{self.state}: {self.reason}' if self.reason else self.state

"""The base of the package's processing nodes: parameters, diagnostics, input QoS, guarded callbacks.

A node derives :class:`SonarNode`, gives its name, its config (a
:class:`~sonar_tracking.core.config.Config` whose settings become parameters) and the name of its
diagnostics, and then only wires subscriptions and publishers to its core component:

* ``self.config`` is always the current config; ``on_change(old, new)`` hears accepted changes;
* ``self.subscribe(type, topic, callback, qos)`` wraps the callback so that an unexpected error
  costs one message, logged and counted under ``internal_error``, never the node; messages the
  middleware lost before the callback (a full queue) are counted under ``queue_overflow`` from
  gaps in the publisher's sequence numbers
  (:class:`~sonar_tracking.ros.diagnostics.SequenceGaps`: rmw_fastrtps_cpp numbers messages,
  rmw_cyclonedds_cpp does not);
* ``self.input_qos(depth)`` is the reader profile the ``input_qos`` parameter names;
* ``self.admit(stamp, what, on_reset)`` applies the time rule (:mod:`sonar_tracking.ros.timeline`)
  and ``self.time.accept(stamp)`` notes a processed stamp;
* ``self.diag`` (:class:`~sonar_tracking.ros.diagnostics.StageDiagnostics`) is published on
  ``diagnostics`` once a second, and at once by ``self.report_now()`` when the node's state changes
  (a node calls it after a reset or an enable; a restart after a jump back in time and an accepted
  parameter change publish it here); ``self.say(...)`` logs a problem at most once a second per kind;
* the node's state (:mod:`sonar_tracking.ros.status`: ``starting`` until it is built and spins,
  then ``learning`` while the seconds of ``self.watch_warmup(left)`` are above 0, else ``ready``)
  is published on ``~/status`` and in the diagnostics (``state``, ``warmup_left_s``), looked at
  after every guarded callback, each diagnostics report and each accepted parameter change.
"""
from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node

from sonar_tracking.core.config import Config, setting
from sonar_tracking.ros.diagnostics import QUEUE_OVERFLOW, SequenceGaps, StageDiagnostics
from sonar_tracking.ros.params import ConfigParameters
from sonar_tracking.ros.qos import INPUT_QOS, input_profile
from sonar_tracking.ros.status import LEARNING, READY, STARTING, NodeStatus
from sonar_tracking.ros.timeline import LATE, RESET, TimeGuard

__all__ = ['InputConfig', 'SonarNode']


@dataclass(frozen=True)
class InputConfig(Config):
    """How a node reads its input: QoS and the time rule (``sonar_tracking.ros.timeline``)."""

    input_qos: str = setting('reliable', 'QoS of the subscriptions to sensor topics (sectors, sector info, imaging '
                             'frames, odometry): reliable, or sensor_data (best effort, what most drivers publish; '
                             'it also reads reliable publishers); topics between the package\'s nodes are always '
                             'reliable', choices=INPUT_QOS, read_only=True)
    time_jump_reset: float = setting(3.0, 'a stamp this much older than the last one restarts the node (a looping '
                                     'bag); smaller steps back are dropped', unit='s', low=0.0, high=1e6)


class SonarNode(Node):
    """A processing node: declared parameters, diagnostics and guarded input (module docstring)."""

    def __init__(self, name: str, config: Config, diag_name: str, *, mutable: set[str] | None = None,
                 skip: tuple[str, ...] = (), check: Callable[[Config], None] | None = None, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.node_status = NodeStatus(self)
        self.diag = StageDiagnostics(diag_name)
        self.pub_diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self._warmup_left: Callable[[], float] | None = None
        self._spinning = False
        self._show_status(STARTING, 0.0)
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))
        self.params = ConfigParameters(self, config, on_change=self._changed, skip=skip, mutable=mutable, check=check)
        self.time = TimeGuard()
        self._restarts = 0
        self.create_timer(1.0, self._publish_diagnostics)
        # Timers run only once the executor spins, which is after the whole node (the subclass
        # included) is built: this one ends the 'starting' state.
        self._start_timer = self.create_timer(0.001, self._started)

    @property
    def config(self) -> Any:
        """The current configuration (kept in step with the parameters)."""
        return self.params.config

    def on_change(self, old: Any, new: Any) -> None:
        """Override to apply an accepted parameter change."""

    def _changed(self, old: Any, new: Any) -> None:
        self.on_change(old, new)
        before, after = old.flat(), new.flat()
        changed = [f'{k}={after[k]}' for k in after if after[k] != before.get(k)]
        self.diag.status['last_parameter_change'] = ', '.join(changed)
        self.report_now()

    # -- state: starting, learning, ready ------------------------------------------------------
    def watch_warmup(self, left: Callable[[], float]) -> None:
        """Say ``learning`` while ``left()``, the seconds of input the node still holds its output
        back for (:func:`sonar_tracking.ros.status.warmup_left`), is above 0, and ``ready`` after."""
        self._warmup_left = left

    def _started(self) -> None:
        self.destroy_timer(self._start_timer)
        self._spinning = True
        self._update_status()
        self.report_now()

    def _update_status(self) -> bool:
        """Look at the node's state; True when it changed (and was published on ``~/status``)."""
        if not self._spinning:
            return False
        try:
            left = self._warmup_left() if self._warmup_left is not None else 0.0
        except Exception as exc:  # noqa: BLE001 - a state that cannot be read must not cost a message
            self.say('error', f'warm-up state unreadable: {type(exc).__name__}: {exc}')
            return False
        return self._show_status(LEARNING if left > 0 else READY, left)

    def _show_status(self, state: str, left: float) -> bool:
        if state == STARTING:
            detail = 'starting: parameters and compiled kernels; no input is taken yet'
        elif state == LEARNING:
            detail = 'learning the structure background: no output for seconds_left more seconds of input'
        else:
            detail = 'ready'
        changed = self.node_status.set(state, left, detail)
        self.diag.status['state'] = state
        if self._warmup_left is not None:
            self.diag.status['warmup_left_s'] = f'{left:.1f}'
        self.diag.condition('status', None if state == READY else (
            f'learning the structure background: {left:.1f} s of input left, no output until then'
            if state == LEARNING else 'starting: no input taken yet'), DiagnosticStatus.OK)
        return changed

    def warm_up(self, run: Callable[..., float], *args: Any) -> None:
        """Run a component's warm-up (:mod:`sonar_tracking.ros.warmup`) before subscribing, so
        its compiled kernels are loaded, or compiled on the first start after an install, before
        the first message waits for them."""
        try:
            seconds = run(*args)
        except Exception as exc:  # noqa: BLE001 - a warm-up must never keep the node from starting
            self.get_logger().warning(f'kernel warm-up failed ({type(exc).__name__}: {exc}); the kernels '
                                      'compile on the first messages instead')
            return
        log = self.get_logger().info if seconds > 1.0 else self.get_logger().debug
        log(f'compiled kernels ready in {seconds:.1f} s')

    def input_qos(self, depth: int = 50):
        """The reader profile named by the ``input_qos`` parameter."""
        return input_profile(self.config.input_qos, depth)

    def admit(self, stamp_ns: int, what: str, on_reset: Callable[[int], None], newest: int | None = None) -> bool:
        """Whether input ``what`` at ``stamp_ns`` is processed: a late stamp is dropped with a warning,
        a jump back restarts the node (``on_reset(last_ns)``, with the newest stamp of the old recording)
        and is processed. ``newest``: a stamp accepted but not yet processed (input waiting for its
        pose), compared instead of the last processed."""
        guard = self.time if newest is None else TimeGuard(newest)
        verdict, back = guard.check(stamp_ns, self.config.time_jump_reset)
        if verdict == LATE:
            last_ns = guard.last_ns or 0   # a late stamp always has a last one
            self.say('warning', f'{what} at {stamp_ns / 1e9:.6f} s is not newer than the last one '
                     f'({last_ns / 1e9:.6f} s): dropped', 'stamp_order')
            return False
        if verdict == RESET:
            self.get_logger().warning(f'time went back by {back:.3f} s (a new recording?): {self.get_name()} '
                                      'starts again')
            last = guard.last_ns or 0   # a jump back always has a last stamp
            self.time.reset()
            on_reset(last)
            self._restarts += 1
            self.diag.status['restarts'] = str(self._restarts)
            self.diag.status['last_restart'] = f'time went back by {back:.3f} s to {stamp_ns / 1e9:.6f} s'
            self.report_now()
        return True

    def subscribe(self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos,
                  on_lost: Callable[[int, Any], None] | None = None) -> Any:
        """A subscription whose callback cannot take the node down and whose lost messages are counted
        (see the module docstring); ``on_lost(count, msg)`` hears of ``count`` messages lost just
        before ``msg``. The callback also takes a message alone (tests feed it so)."""
        run = self.guarded(callback, f'{topic} message')
        heard_lost = None if on_lost is None else self.guarded(on_lost, f'{topic} message')
        gaps = SequenceGaps()
        subscription: list[Any] = []

        def take(msg: Any, info: Any = None) -> None:
            if info is not None and subscription:
                lost = self._count_lost(subscription[0], gaps, info)
                if lost and heard_lost is not None:
                    heard_lost(lost, msg)
            run(msg)
        # rclpy hands the message info only to a callback that cannot be called with the message alone.
        take.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
            [inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in ('msg', 'info')])
        subscription.append(self.create_subscription(msg_type, topic, take, qos))
        return subscription[0]

    def _count_lost(self, subscription: Any, gaps: SequenceGaps, info: Any) -> int:
        try:
            lost = gaps.lost(info.get('publication_sequence_number'), subscription.get_publisher_count())
        except Exception as exc:  # noqa: BLE001 - counting must never cost the message itself
            self.say('error', f'{subscription.topic_name}: message info unreadable: {type(exc).__name__}: {exc}')
            return 0
        if lost:
            self.diag.report(self.get_logger(), QUEUE_OVERFLOW,
                             f'{lost} {subscription.topic_name} messages lost before they were read (a full '
                             'queue: the node or the network fell behind the publisher)', 'warning', count=lost)
        return lost

    def guarded(self, callback: Callable[..., None], what: str) -> Callable[..., None]:
        """``callback`` wrapped so an unexpected exception drops ``what`` with a logged reason."""
        def run(*args: Any) -> None:
            try:
                callback(*args)
            except Exception as exc:  # noqa: BLE001 - a bug must cost one message, not the node
                self.say('error', f'{what} dropped after an internal error: {type(exc).__name__}: {exc}',
                         reason='internal_error')
            if self._update_status():
                self.report_now()
        return run

    def say(self, severity: str, text: str, reason: str | None = None) -> None:
        """Log ``text`` (``error``, ``warning`` or ``info``), each kind of problem at most once a second;
        with ``reason``, also count a dropped message under it."""
        if reason is not None:
            self.diag.report(self.get_logger(), reason, text, severity)
        else:
            self.diag.log(self.get_logger(), StageDiagnostics.kind(text), text, severity)

    def report_now(self) -> None:
        """Publish the diagnostics at once (a state change: reset, enable, restart), besides the
        once-a-second report."""
        self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        self._update_status()
        # Matched readers per output: whether anyone receives this node's results (and a condition tests wait on).
        own = (self.pub_diag, self.node_status.pub)
        self.diag.listeners = {p.topic_name: p.get_subscription_count() for p in self.publishers
                               if p not in own and p.topic_name != '/parameter_events'}
        self.diag.values.update(self.status_values())
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))

    def status_values(self) -> dict[str, str]:
        """Override: diagnostics values read when the report is published (state that changes
        between processed messages, such as the latest pose)."""
        return {}

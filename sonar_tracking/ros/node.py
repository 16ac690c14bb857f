"""The base of the package's processing nodes: parameters, diagnostics, input QoS, guarded callbacks.

A node derives :class:`SonarNode`, gives its name, its config (a
:class:`~sonar_tracking.core.config.Config` whose settings become parameters) and the name of its
diagnostics, and then only wires subscriptions and publishers to its core component:

* ``self.config`` is always the current config; ``on_change(old, new)`` hears accepted changes;
* ``self.subscribe(type, topic, callback, qos)`` wraps the callback so that an unexpected error
  costs one message, logged and counted under ``internal_error``, never the node;
* ``self.input_qos(depth)`` is the reader profile the ``input_qos`` parameter names;
* ``self.admit(stamp, what, on_reset)`` applies the time rule (:mod:`sonar_tracking.ros.timeline`)
  and ``self.time.accept(stamp)`` notes a processed stamp;
* ``self.diag`` (:class:`~sonar_tracking.ros.diagnostics.StageDiagnostics`) is published on
  ``diagnostics`` once a second; ``self.say(...)`` logs a problem at most once a second per kind.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node

from sonar_tracking.core.config import Config, setting
from sonar_tracking.ros.diagnostics import StageDiagnostics
from sonar_tracking.ros.params import ConfigParameters
from sonar_tracking.ros.qos import INPUT_QOS, input_profile
from sonar_tracking.ros.timeline import LATE, RESET, TimeGuard

__all__ = ['InputConfig', 'SonarNode']


@dataclass(frozen=True)
class InputConfig(Config):
    """How a node reads its input: QoS and the time rule (``sonar_tracking.ros.timeline``)."""

    input_qos: str = setting('reliable', 'QoS of the input subscriptions: reliable, or sensor_data (best effort, '
                             'what most sonar drivers publish; it also reads reliable publishers)',
                             choices=INPUT_QOS, read_only=True)
    time_jump_reset: float = setting(3.0, 'a stamp this much older than the last one restarts the node (a looping '
                                     'bag); smaller steps back are dropped', unit='s', low=0.0, high=1e6)


class SonarNode(Node):
    """A processing node: declared parameters, diagnostics and guarded input (module docstring)."""

    def __init__(self, name: str, config: Config, diag_name: str, *, mutable: set[str] | None = None,
                 skip: tuple[str, ...] = (), check: Callable[[Config], None] | None = None, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.params = ConfigParameters(self, config, on_change=self.on_change, skip=skip, mutable=mutable, check=check)
        self.diag = StageDiagnostics(diag_name)
        self.time = TimeGuard()
        self.pub_diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self.create_timer(1.0, self._publish_diagnostics)

    @property
    def config(self) -> Any:
        """The current configuration (kept in step with the parameters)."""
        return self.params.config

    def on_change(self, old: Any, new: Any) -> None:
        """Override to apply an accepted parameter change."""

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
        return True

    def subscribe(self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos) -> Any:
        """A subscription whose callback cannot take the node down (see the module docstring)."""
        return self.create_subscription(msg_type, topic, self.guarded(callback, f'{topic} message'), qos)

    def guarded(self, callback: Callable[..., None], what: str) -> Callable[..., None]:
        """``callback`` wrapped so an unexpected exception drops ``what`` with a logged reason."""
        def run(*args: Any) -> None:
            try:
                callback(*args)
            except Exception as exc:  # noqa: BLE001 - a bug must cost one message, not the node
                self.say('error', f'{what} dropped after an internal error: {type(exc).__name__}: {exc}',
                         reason='internal_error')
        return run

    def say(self, severity: str, text: str, reason: str | None = None) -> None:
        """Log ``text`` (``error``, ``warning`` or ``info``), each kind of problem at most once a second;
        with ``reason``, also count a dropped message under it."""
        if reason is not None:
            self.diag.report(self.get_logger(), reason, text, severity)
        else:
            self.diag.log(self.get_logger(), StageDiagnostics.kind(text), text, severity)

    def _publish_diagnostics(self) -> None:
        # Matched readers per output: whether anyone receives this node's results (and a condition tests wait on).
        self.diag.listeners = {p.topic_name: p.get_subscription_count() for p in self.publishers
                               if p is not self.pub_diag and p.topic_name != '/parameter_events'}
        self.diag.values.update(self.status_values())
        self.pub_diag.publish(self.diag.array(self.get_clock().now().to_msg()))

    def status_values(self) -> dict[str, str]:
        """Override: diagnostics values read when the report is published (state that changes
        between processed messages, such as the latest pose)."""
        return {}

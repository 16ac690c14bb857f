"""How every process of the package runs ROS: DDS defaults, parent watch, the ros2/demos main().

**Stopping a node.** SIGINT (Ctrl-C) and SIGTERM stop :func:`run_node` between two callbacks, and
everything the stop does happens in the main thread, in order: the running callback finishes, the
executor shuts down, the node is destroyed, ROS is shut down. A signal while the node is being built
(its kernel warm-up included) stops it as soon as the build is done: an exception raised at an
arbitrary point of the build would land in third-party code (numba's compiler swallows it in a
finaliser and may keep its lock), and the node then neither stops nor works. A second signal ends
the process at once, in any phase. rclpy's own signal handling is not
installed: it shuts ROS down from a thread of its own at the signal (rclpy ``signal_handler.cpp``:
trigger every executor's SIGINT guard condition, then ``rcl_shutdown`` every context), while the
main thread, interrupted by the KeyboardInterrupt of the same signal, tears the executor and the
node down. When a loaded machine delays that thread, it triggers the guard condition the main
thread has destroyed already: the node dies with SIGSEGV (or a traceback) instead of exiting.

**Start-up errors.** ROS arguments rcl cannot take (a parameter file it cannot parse, a malformed
``-p`` rule, an unknown argument) end the process with one line saying what to fix and status 2.
"""
from __future__ import annotations

import os
import re
import signal
import sys
import tempfile
import threading
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from sonar_tracking import process

if TYPE_CHECKING:
    import rclpy.node

__all__ = ['run_node', 'start_ros', 'prepare_process', 'configure_dds', 'private_domain',
           'exit_if_teardown_hangs', 'StartError', 'EXIT_START_ERROR', 'STOP_SIGNALS']

#: Exit status of a node whose ROS arguments rcl refused.
EXIT_START_ERROR = 2
#: The signals that stop a node.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Longest wait for ROS work between two looks at a stop request (the reaction time to a signal
#: while the node is idle).
_STOP_POLL_S = 0.1


class StartError(RuntimeError):
    """ROS could not start with the given arguments; the message says why."""


def prepare_process() -> None:
    """Call first in every ROS entry point: DDS defaults, :func:`sonar_tracking.process.prepare`, and
    under ``sonar_stack`` a parent watch.

    ``sonar_stack`` sets ``SONAR_TRACKING_DIE_WITH_PARENT``: the process then asks Linux for SIGTERM
    when its parent ends (:func:`sonar_tracking.process.die_with_parent`), so a killed stack leaves
    no orphans. ``SONAR_TRACKING_PARENT_PID`` (:data:`sonar_tracking.process.PARENT_ENV`), the
    starting process's pid, closes the gap before that request: a parent that ended meanwhile ends
    this process at once. It is taken out of the environment, so this process's own children do not
    inherit a pid that is not their parent's.
    """
    configure_dds()
    process.prepare()
    parent = os.environ.pop(process.PARENT_ENV, '')
    if os.environ.get('SONAR_TRACKING_DIE_WITH_PARENT') or parent:
        process.die_with_parent(signal.SIGTERM, int(parent) if parent.isdigit() else None)


def configure_dds() -> None:
    """Use the package's Fast DDS profile unless the user chose one or another middleware.

    Must run before ``rclpy.init``: Fast DDS reads the profile when the participant is created.
    """
    rmw = os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    if 'fastrtps' in rmw and not os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(resources.files('sonar_tracking') / 'data' / 'fastdds.xml')


def private_domain() -> int:
    """Put this process and the children it starts in a DDS domain of their own (from the pid), so a
    benchmark or test sees only its own nodes, whatever else runs on the machine. Before ``rclpy.init``."""
    domain = 101 + os.getpid() % 100   # 101-200: clear of the default 0 and of the tests' 1-100
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return domain


class _Stop:
    """SIGINT and SIGTERM in :func:`run_node`: the first signal only sets :attr:`requested`, which
    the caller reads between steps (no exception is raised into running code); a second one ends
    the process at once (the kernel's default action), for a build or teardown that hangs."""

    def __init__(self) -> None:
        self.requested = False
        for signum in STOP_SIGNALS:
            signal.signal(signum, self._on_signal)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        if self.requested:
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        self.requested = True

    def tear_down(self) -> None:
        for signum in STOP_SIGNALS:
            signal.signal(signum, signal.SIG_DFL)


def _rcl_reason(exc: Exception) -> str:
    """rcl's message without its source locations (``, at /path/file.c:123``) and prefix."""
    text = re.sub(r',? at \S+:\d+', '', str(exc)).strip()
    text = re.sub(r'^failed to initialize rcl: ', '', text)
    if type(exc).__name__ == 'UnknownROSArgsError':
        text = 'unknown ROS arguments: ' + text.strip('[]').replace("'", '')
    return text


def start_ros(args: list[str] | None = None) -> None:
    """``rclpy.init(args)`` without rclpy's signal handlers (module docstring). ROS arguments rcl
    refuses raise :class:`StartError` with its reason; rcl's own log line about them is held back,
    anything else it prints on a good start is passed on."""
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.signals import SignalHandlerOptions
    refused: Exception | None = None
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        try:
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except (_rclpy.RCLError, _rclpy.UnknownROSArgsError) as exc:
            refused = exc
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        if refused is None:
            held.seek(0)
            os.write(2, held.read())
            return
    raise StartError(_rcl_reason(refused))


def run_node(factory: Callable[[], rclpy.node.Node], args: list[str] | None = None) -> int:
    """Init rclpy, spin the node until SIGINT, SIGTERM or shutdown, clean up; returns the exit status
    (:data:`EXIT_START_ERROR`, after one line on stderr, when rcl refuses the ROS arguments). The
    stop happens between callbacks, all of it in this thread (module docstring)."""
    prepare_process()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    stop = _Stop()
    try:
        start_ros(args)
    except StartError as exc:
        name = Path((args or sys.argv or ['node'])[0]).stem or 'node'
        print(f'{name}: cannot start: {exc}', file=sys.stderr, flush=True)
        return EXIT_START_ERROR
    executor = SingleThreadedExecutor()
    node = None
    try:
        if not stop.requested:
            node = factory()
            executor.add_node(node)
        while not stop.requested and executor.context.ok():
            executor.spin_once(timeout_sec=_STOP_POLL_S)
    except ExternalShutdownException:
        pass
    except Exception:
        # The factory stopped by a shutdown of the context under it (by its own code, or a caller
        # of rclpy.shutdown): a stop, not a failure.
        if rclpy.ok():
            raise
    finally:
        stop.tear_down()
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def exit_if_teardown_hangs(status: int = 0, seconds: float = 10.0) -> None:
    """Leave the process with ``status`` if it is still here ``seconds`` from now. For a tool whose
    work is done (every message sent and acknowledged) before it tears ROS down: the teardown of
    rclpy and DDS can hang now and then (ros2/rclpy#456, eProsima/Fast-DDS#235), and a tool that
    never exits stalls whatever waits for it."""
    def leave() -> None:
        print(f'ROS teardown took over {seconds:g} s: exiting without it', file=sys.stderr, flush=True)
        os._exit(status)
    timer = threading.Timer(seconds, leave)
    timer.daemon = True
    timer.start()

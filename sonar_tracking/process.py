"""What every process of the package sets up where it starts: glibc allocator settings and the
removal of stale compiled-kernel caches. Standard library only, so every layer may import it.

**Allocator.**
numpy temporaries of the trackers (per-pair and per-track arrays of tens to hundreds of kB)
lie above glibc's default ``mmap`` threshold (128 kB, raised dynamically only after a free), so
each step maps fresh pages and page-faults them, and trims the heap after it. With the
thresholds below, the memory is taken from the heap and kept for the next step. The price: a
process keeps up to ``MALLOC_TRIM_THRESHOLD_`` of freed heap instead of returning it at once.

glibc reads these variables when a process starts; a running process sets the same values with
``mallopt`` (:func:`apply_in_process`, through :func:`prepare` where every process of the package
starts: the nodes' and tools' ``prepare_process``, ``sonar_eval``, the kernel warm-up).
:func:`allocator_env` gives the environment for a child process that is not one of ours. A value
already in the environment is kept (the user's choice wins), and ``SONAR_TRACKING_MALLOC=0``
switches the whole thing off.

**Kernel caches.** numba checks a cached kernel (``sonar_tracking.core.jit``) against its own source
file only, not against the kernels it calls from other files, so an edited callee would leave its
callers' cached code stale. :func:`drop_stale_kernel_caches` drops every cached kernel under
``sonar_tracking/core`` older than the newest source file there (a no-op on an installed package,
whose sources do not change). :func:`prepare` does both.

**Parent death.** A process the package starts must not outlive the one that started it, however
that one ends (a CI timeout's SIGKILL included). Linux sends a chosen signal to a process when its
parent ends (``PR_SET_PDEATHSIG``, kept across ``exec``): :func:`child_dies_with_parent` asks for it
in a child between fork and exec (a ``preexec_fn``), :func:`die_with_parent` in the process itself.
The request names the parent *thread*: a child must be started from a thread that lives as long as
the parent does (the main thread).
"""
from __future__ import annotations

import os
import platform
import signal
from collections.abc import Callable, Mapping
from pathlib import Path

__all__ = ['ALLOCATOR_SETTINGS', 'allocator_env', 'allocator_applied', 'apply_in_process', 'drop_stale_kernel_caches',
           'prepare', 'die_with_parent', 'child_dies_with_parent', 'PARENT_ENV']

#: Variable -> value. 32 MiB is the largest mmap threshold glibc accepts on 64-bit.
ALLOCATOR_SETTINGS: dict[str, str] = {
    'MALLOC_MMAP_THRESHOLD_': str(32 * 1024 * 1024),
    'MALLOC_TRIM_THRESHOLD_': str(256 * 1024 * 1024),
    'MALLOC_TOP_PAD_': str(64 * 1024 * 1024),
}
_SWITCH = 'SONAR_TRACKING_MALLOC'


def _enabled(env: Mapping[str, str]) -> bool:
    return env.get(_SWITCH, '1') != '0' and platform.system() == 'Linux'


def allocator_env(env: Mapping[str, str] | None = None) -> dict[str, str]:
    """A copy of ``env`` (default ``os.environ``) with the allocator settings added where unset."""
    out = dict(os.environ if env is None else env)
    if _enabled(out):
        for key, value in ALLOCATOR_SETTINGS.items():
            out.setdefault(key, value)
    return out


def allocator_applied(env: Mapping[str, str] | None = None) -> bool:
    """True when ``env`` (default ``os.environ``) already holds every setting, or they are switched off."""
    env = os.environ if env is None else env
    return not _enabled(env) or all(k in env for k in ALLOCATOR_SETTINGS)


#: mallopt parameter numbers (glibc malloc.h) of the settings.
_MALLOPT = {'MALLOC_TRIM_THRESHOLD_': -1, 'MALLOC_TOP_PAD_': -2, 'MALLOC_MMAP_THRESHOLD_': -3}


def apply_in_process() -> bool:
    """Set the allocator settings in this process with glibc's ``mallopt`` (a setting the user gave
    in the environment is left as glibc read it). True when they are in force."""
    if not _enabled(os.environ):
        return False
    try:
        import ctypes
        libc = ctypes.CDLL('libc.so.6')
    except OSError:
        return False
    ok = True
    for key, value in ALLOCATOR_SETTINGS.items():
        if key not in os.environ:
            ok &= libc.mallopt(_MALLOPT[key], int(value)) == 1
    return bool(ok)


#: Where the compiled kernels live.
KERNEL_ROOT = Path(__file__).resolve().parent / 'core'


def drop_stale_kernel_caches(root: Path = KERNEL_ROOT) -> None:
    """Remove numba cache files (``.nbi``, ``.nbc``) under ``root`` older than its newest ``.py`` file."""
    newest, caches = 0.0, []
    for folder, _, files in os.walk(root):
        for name in files:
            path = os.path.join(folder, name)
            if name.endswith('.py'):
                newest = max(newest, os.stat(path).st_mtime)
            elif name.endswith(('.nbi', '.nbc')):
                caches.append(path)
    for path in caches:
        try:
            if os.stat(path).st_mtime < newest:
                os.unlink(path)
        except OSError:        # removed by another process meanwhile, or not ours to remove
            pass


def prepare() -> bool:
    """Set up this process: stale kernel caches dropped, allocator settings applied (the result of
    :func:`apply_in_process`). Called where the package's processes start."""
    drop_stale_kernel_caches()
    return apply_in_process()


#: ``prctl`` option number (linux/prctl.h).
_PR_SET_PDEATHSIG = 1
#: Set in a child's environment to the pid of the process that starts it: :func:`die_with_parent`
#: then knows when the parent ended before the child could ask to end with it.
PARENT_ENV = 'SONAR_TRACKING_PARENT_PID'


def _prctl() -> Callable[..., int] | None:
    try:
        import ctypes
        return ctypes.CDLL('libc.so.6', use_errno=True).prctl
    except (OSError, AttributeError):   # not glibc Linux
        return None


def die_with_parent(signum: int = signal.SIGTERM, parent: int | None = None) -> bool:
    """Have Linux send this process ``signum`` when its parent ends. ``parent``: the pid that started
    this process; when this process has another parent already (it was adopted, its parent having
    ended before this call), it sends itself ``signum`` at once. False where Linux cannot do it."""
    prctl = _prctl()
    if prctl is None or prctl(_PR_SET_PDEATHSIG, int(signum), 0, 0, 0) != 0:
        return False
    if parent is not None and os.getppid() != parent:
        os.kill(os.getpid(), signum)
    return True


def child_dies_with_parent(signum: int = signal.SIGTERM, then: Callable[[], None] | None = None
                           ) -> Callable[[], None]:
    """A ``preexec_fn`` for :class:`subprocess.Popen`: the child gets ``signum`` when this process (the
    calling thread: start children from the main thread) ends, however it ends; a child whose parent
    is gone before the request is made gets it at once. ``then``: the caller's own ``preexec_fn``,
    run after the request. The C function is looked up before the fork, so between fork and exec
    the child makes only the request and the check of its parent."""
    parent, prctl = os.getpid(), _prctl()

    def preexec() -> None:
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, int(signum), 0, 0, 0)
            if os.getppid() != parent:
                os.kill(os.getpid(), signum)
        if then is not None:
            then()
    return preexec

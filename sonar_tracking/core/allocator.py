"""glibc allocator settings for the package's processes, applied where a process starts.

numpy temporaries of the trackers (per-pair and per-track arrays of tens to hundreds of kB)
lie above glibc's default ``mmap`` threshold (128 kB, raised dynamically only after a free), so
each step maps fresh pages and page-faults them, and trims the heap after it. With the
thresholds below, the memory is taken from the heap and kept for the next step. The price: a
process keeps up to ``MALLOC_TRIM_THRESHOLD_`` of freed heap instead of returning it at once.

glibc reads these variables once, when the process starts, so they cannot be set from inside
a running interpreter. :func:`allocator_env` gives the environment for a child process;
:func:`reexec_with_allocator` restarts the current program with it (call it first thing in a
``main()``). A value already in the environment is kept (the user's choice wins), and
``SONAR_TRACKING_MALLOC=0`` switches the whole thing off.
"""
from __future__ import annotations

import os
import platform
import sys
from collections.abc import Mapping

__all__ = ['ALLOCATOR_SETTINGS', 'allocator_env', 'allocator_applied', 'reexec_with_allocator']

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


def reexec_with_allocator(argv: list[str] | None = None) -> None:
    """Restart this Python program with :func:`allocator_env` unless it already runs with it.

    Replaces the process (``os.execve``); returns only when nothing needs doing. ``argv`` (the
    interpreter's arguments) defaults to ``sys.argv``, or ``-m MODULE ...`` when the program was
    started with ``python -m``. Call it before any other work: what ran before is redone.
    """
    if allocator_applied():
        return
    if argv is None:
        main = sys.modules.get('__main__')
        spec = getattr(main, '__spec__', None)
        # Started with ``python -m pkg.mod``: restart the same way, so package imports keep working.
        argv = ['-m', spec.name, *sys.argv[1:]] if spec is not None and spec.name else list(sys.argv)
    args = [sys.executable, *argv]
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, args, allocator_env())

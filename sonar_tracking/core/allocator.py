"""glibc allocator settings for the package's processes, applied where a process starts.

numpy temporaries of the trackers (per-pair and per-track arrays of tens to hundreds of kB)
lie above glibc's default ``mmap`` threshold (128 kB, raised dynamically only after a free), so
each step maps fresh pages and page-faults them, and trims the heap after it. With the
thresholds below, the memory is taken from the heap and kept for the next step. The price: a
process keeps up to ``MALLOC_TRIM_THRESHOLD_`` of freed heap instead of returning it at once.

glibc reads these variables when a process starts; a running process sets the same values with
``mallopt`` (:func:`apply_in_process`, called where every process of the package starts: the
nodes' and tools' ``prepare_process``, ``sonar_eval``). :func:`allocator_env` gives the
environment for a child process that is not one of ours. A value already in the environment is
kept (the user's choice wins), and ``SONAR_TRACKING_MALLOC=0`` switches the whole thing off.
"""
from __future__ import annotations

import os
import platform
from collections.abc import Mapping

__all__ = ['ALLOCATOR_SETTINGS', 'allocator_env', 'allocator_applied', 'apply_in_process']

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

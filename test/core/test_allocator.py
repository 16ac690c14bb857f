"""glibc allocator settings: the environment for child processes and the re-exec decision."""
from __future__ import annotations

import subprocess
import sys

from sonar_tracking.core import allocator


def test_env_adds_the_settings_and_keeps_the_users_own():
    env = allocator.allocator_env({'PATH': '/bin', 'MALLOC_TRIM_THRESHOLD_': '1'})
    assert env['PATH'] == '/bin' and env['MALLOC_TRIM_THRESHOLD_'] == '1'
    assert env['MALLOC_MMAP_THRESHOLD_'] == allocator.ALLOCATOR_SETTINGS['MALLOC_MMAP_THRESHOLD_']
    assert allocator.allocator_applied(env) and not allocator.allocator_applied({'PATH': '/bin'})


def test_switched_off_adds_nothing():
    env = allocator.allocator_env({'SONAR_TRACKING_MALLOC': '0'})
    assert not any(k in env for k in allocator.ALLOCATOR_SETTINGS)
    assert allocator.allocator_applied(env)


_PROBE = """
import ctypes, sys
from sonar_tracking.core.allocator import apply_in_process
class Mallinfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ('arena', 'ordblks', 'smblks', 'hblks', 'hblkhd', 'usmblks',
                                               'fsmblks', 'uordblks', 'fordblks', 'keepcost')]
libc = ctypes.CDLL('libc.so.6')
libc.mallinfo2.restype = Mallinfo2
applied = apply_in_process() if sys.argv[1] == 'apply' else False
import numpy as np
a = np.ones(4 * 1024 * 1024 // 8)      # 4 MiB: above glibc's default mmap threshold (128 kB)
print(applied, libc.mallinfo2().hblkhd >= 4 * 1024 * 1024)
"""


def test_in_process_settings_keep_large_temporaries_on_the_heap(tmp_path):
    """With the settings a 4 MiB array comes from the heap (kept for the next step), without them from
    a fresh mmap (page-faulted each time)."""
    env = {k: v for k, v in allocator.allocator_env().items() if k not in allocator.ALLOCATOR_SETTINGS}
    script = tmp_path / 'probe.py'
    script.write_text(_PROBE)

    def probe(mode):
        return subprocess.run([sys.executable, str(script), mode], env=env, capture_output=True, text=True,
                              check=True, timeout=60).stdout.split()
    assert probe('apply') == ['True', 'False']
    assert probe('plain') == ['False', 'True']
    off = subprocess.run([sys.executable, str(script), 'apply'], env=env | {'SONAR_TRACKING_MALLOC': '0'},
                         capture_output=True, text=True, check=True, timeout=60).stdout.split()
    assert off == ['False', 'True']

"""Process set-up (sonar_tracking.process): glibc allocator settings (the environment for child
processes and the re-exec decision), the removal of stale kernel caches, and children that end
with their parent."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from sonar_tracking import process


def test_env_adds_the_settings_and_keeps_the_users_own():
    env = process.allocator_env({'PATH': '/bin', 'MALLOC_TRIM_THRESHOLD_': '1'})
    assert env['PATH'] == '/bin' and env['MALLOC_TRIM_THRESHOLD_'] == '1'
    assert env['MALLOC_MMAP_THRESHOLD_'] == process.ALLOCATOR_SETTINGS['MALLOC_MMAP_THRESHOLD_']
    assert process.allocator_applied(env) and not process.allocator_applied({'PATH': '/bin'})


def test_switched_off_adds_nothing():
    env = process.allocator_env({'SONAR_TRACKING_MALLOC': '0'})
    assert not any(k in env for k in process.ALLOCATOR_SETTINGS)
    assert process.allocator_applied(env)


_PROBE = """
import ctypes, sys
from sonar_tracking.process import apply_in_process
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
    env = {k: v for k, v in process.allocator_env().items() if k not in process.ALLOCATOR_SETTINGS}
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


def test_cached_kernels_older_than_any_core_source_are_dropped(tmp_path):
    """numba checks a cached kernel against its own file only; a cache older than the newest source
    in the tree (an edited callee in another file) must go, a newer one stays."""
    (tmp_path / 'tracking' / '__pycache__').mkdir(parents=True)
    source = tmp_path / 'tracking' / 'callee.py'
    source.write_text('x = 1\n')
    stale = tmp_path / 'tracking' / '__pycache__' / 'caller._f-10.py311.nbi'
    fresh = tmp_path / 'tracking' / '__pycache__' / 'caller._f-10.py311.1.nbc'
    other = tmp_path / 'tracking' / '__pycache__' / 'callee.cpython-311.pyc'
    for path in (stale, fresh, other):
        path.write_bytes(b'\0')
    os.utime(stale, (1000.0, 1000.0))
    os.utime(source, (2000.0, 2000.0))
    os.utime(fresh, (3000.0, 3000.0))
    os.utime(other, (1000.0, 1000.0))
    process.drop_stale_kernel_caches(tmp_path)
    assert not stale.exists()
    assert fresh.exists() and other.exists() and source.exists()


_PARENT = """
import subprocess, sys, threading
from sonar_tracking.process import child_dies_with_parent
child = subprocess.Popen([sys.executable, '-c', 'import threading; threading.Event().wait(600)'],
                         preexec_fn=child_dies_with_parent())
print(child.pid, flush=True)
threading.Event().wait(600)
"""


def _alive(pid: int) -> bool:
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'   # a zombie has ended
    except FileNotFoundError:
        return False


def _wait_until(predicate, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def test_a_child_that_asked_ends_when_its_parent_is_killed():
    """child_dies_with_parent: the parent killed with SIGKILL (no handler of its own runs), its child
    gets SIGTERM from the kernel and ends."""
    parent = subprocess.Popen([sys.executable, '-c', _PARENT], stdout=subprocess.PIPE, text=True,
                              start_new_session=True)
    child = int(parent.stdout.readline())
    try:
        assert _alive(child)
        parent.kill()
        parent.wait()
        assert _wait_until(lambda: not _alive(child), 20.0), 'the child outlived its killed parent'
    finally:
        if _alive(child):
            os.kill(child, signal.SIGKILL)


def test_a_process_whose_parent_is_already_gone_ends_at_once():
    """die_with_parent with the pid of a parent that is no longer this process's parent (it ended
    before the request could be made): the process gets the signal at once."""
    script = ('import os, signal\nfrom sonar_tracking.process import die_with_parent\n'
              'die_with_parent(signal.SIGTERM, parent=os.getpid())\nprint("still running")\n')
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60)
    assert r.returncode == -signal.SIGTERM and 'still running' not in r.stdout
    script = script.replace('parent=os.getpid()', 'parent=os.getppid()')
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and 'still running' in r.stdout    # its parent is there: it runs on

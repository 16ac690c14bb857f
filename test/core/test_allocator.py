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


def test_reexec_restarts_once_with_the_settings(tmp_path):
    script = tmp_path / 'child.py'
    script.write_text('import os, sys\n'
                      'from sonar_tracking.core.allocator import reexec_with_allocator\n'
                      'print("start", flush=True)\n'
                      'reexec_with_allocator()\n'
                      'print(os.environ.get("MALLOC_MMAP_THRESHOLD_"), sys.argv[1:])\n')
    env = {k: v for k, v in allocator.allocator_env().items() if k not in allocator.ALLOCATOR_SETTINGS}
    out = subprocess.run([sys.executable, str(script), 'a', 'b'], env=env, capture_output=True, text=True,
                         check=True, timeout=60).stdout.split('\n')
    assert out[:3] == ['start', 'start', f"{allocator.ALLOCATOR_SETTINGS['MALLOC_MMAP_THRESHOLD_']} ['a', 'b']"]


def test_reexec_of_a_module_run_keeps_it_a_module(tmp_path):
    pkg = tmp_path / 'pkg_alloc'
    pkg.mkdir()
    (pkg / '__init__.py').write_text('VALUE = "pkg"\n')
    (pkg / 'main.py').write_text('import os\n'
                                 'from . import VALUE\n'
                                 'from sonar_tracking.core.allocator import reexec_with_allocator\n'
                                 'reexec_with_allocator()\n'
                                 'print(VALUE, os.environ.get("MALLOC_TRIM_THRESHOLD_"))\n')
    env = {k: v for k, v in allocator.allocator_env().items() if k not in allocator.ALLOCATOR_SETTINGS}
    env['PYTHONPATH'] = f'{tmp_path}:{env.get("PYTHONPATH", "")}'
    out = subprocess.run([sys.executable, '-m', 'pkg_alloc.main'], env=env, capture_output=True, text=True,
                         check=True, timeout=60).stdout.strip()
    assert out == f"pkg {allocator.ALLOCATOR_SETTINGS['MALLOC_TRIM_THRESHOLD_']}"

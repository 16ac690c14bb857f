"""The compiled-kernel settings (sonar_tracking.core.jit)."""
from __future__ import annotations

import os

import numpy as np

from sonar_tracking.core import jit


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
    jit._drop_stale_caches(tmp_path)
    assert not stale.exists()
    assert fresh.exists() and other.exists() and source.exists()


def test_kernels_follow_numpy_for_division_by_zero():
    """numpy's error model: a division by zero gives inf or NaN, as numpy does, and raises nothing."""
    @jit.kernel
    def divide(a, b):
        return a / b
    assert divide(1.0, 0.0) == np.inf
    assert np.isnan(divide(0.0, 0.0))


def test_without_a_writable_cache_location_kernels_still_compile(monkeypatch):
    """A read-only install with no writable home: numba finds nowhere to cache; the kernel is compiled
    in the process instead of failing the import."""
    from numba.core import caching
    monkeypatch.setattr(caching.CacheImpl, '_locator_classes', [])

    @jit.kernel
    def twice(a):
        return 2.0 * a
    assert twice(1.5) == 3.0

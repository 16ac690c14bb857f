"""The compiled-kernel settings (sonar_tracking.core.jit)."""
from __future__ import annotations

import numpy as np

from sonar_tracking.core import jit


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

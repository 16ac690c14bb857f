"""Compiled kernels: numba's ``njit`` with the project's settings, in one place.

The tracker's per-scan work at small sizes is a few hundred tiny array operations, so numpy's
fixed cost per call (about 1 us) dominates it; the kernels do the same arithmetic per track in
compiled loops. Settings: IEEE arithmetic (no ``fastmath``, so no reassociation or fused
multiply-adds), numpy's error model (division by zero gives inf or NaN, as numpy does, instead of
raising), the GIL released, and compiled code cached beside the source (``__pycache__``; numba
falls back to a per-user cache where that is not writable), so a process loads it instead of
compiling.

numba checks a cached kernel against its own source file only, not against the kernels it calls
from other files, so an edited callee would leave its callers' cached code stale: the package's
processes drop such caches where they start (:func:`sonar_tracking.process.drop_stale_kernel_caches`).
"""
from __future__ import annotations

import numba

__all__ = ['kernel']


def kernel(fn):
    """``fn`` compiled by numba (lazily, per argument types) with the settings above."""
    try:
        return numba.njit(cache=True, nogil=True, error_model='numpy')(fn)
    except RuntimeError:       # no writable cache location at all: compile in every process instead
        return numba.njit(cache=False, nogil=True, error_model='numpy')(fn)

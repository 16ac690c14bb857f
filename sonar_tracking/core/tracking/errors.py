"""Errors of the tracking core."""
from __future__ import annotations

__all__ = ['TrackingError', 'TrackingInputError']


class TrackingError(ValueError):
    """Base of every error the tracking core raises on purpose."""


class TrackingInputError(TrackingError):
    """The arguments of a call have the wrong shape or type; the message says what was expected.

    Per-row problems of the measurements (NaN, a covariance that is not positive definite, a
    clutter density that is not positive) are not raised: the tracker drops those rows and
    reports them (:class:`~sonar_tracking.core.tracking.measurements.Rejection`).
    """

"""Errors raised by sonar_tracking.msgs."""

__all__ = ['AdapterError']


class AdapterError(ValueError):
    """A message cannot be converted: the text says which field is wrong and what was expected."""

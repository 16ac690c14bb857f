"""Errors raised by msg_adapters."""

__all__ = ['AdapterError']


class AdapterError(ValueError):
    """A message cannot be converted: the text says which field is wrong and what was expected."""

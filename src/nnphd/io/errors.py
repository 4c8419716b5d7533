"""The error of bad user input, shared by every layer (no dependencies, so the command line can catch it cheaply)."""

from __future__ import annotations

__all__ = ["DataError"]


class DataError(ValueError):
    """A user data file that cannot be used; the message is one line naming what is wrong and what was expected."""

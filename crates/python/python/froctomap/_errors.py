"""The one exception class of froctomap."""

from __future__ import annotations


class FroctError(OSError, ValueError):
    """A froctomap operation failed: a missing, unreadable, damaged or foreign file, a bad
    time or option, or inputs a build cannot use.

    It is an ``OSError`` (files) and a ``ValueError`` (values), so either ``except`` clause
    catches it. ``str(error)`` is the message the ``froctomap`` command line prints for the
    same failure; ``errno`` is set when an operating-system error is the cause (e.g.
    ``errno.ENOENT`` for a missing file).
    """

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""

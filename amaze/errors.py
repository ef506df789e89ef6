"""Errors raised for bad user input.

Every error a user can trigger with a bad maze string, sign specification or
argument is a :class:`ValueError` subclass whose message names the offending
token or value, so callers can catch ``ValueError`` and command-line tools can
print one line and exit with status 2.
"""

from __future__ import annotations


class AmazeError(ValueError):
    """Base class of the errors caused by bad user input."""


class MazeStringError(AmazeError):
    """A maze string (or one of its tokens) is malformed or out of range."""


class SignError(AmazeError):
    """A sign specification (shape, lightness or custom image) is invalid."""


class UsageError(AmazeError):
    """A mistake in a command line (an unknown option, a missing ``--out``...)."""


class EpisodeEndedError(AmazeError):
    """An agent was stepped after its episode reached the goal or the deadline.

    The reference library added the finish bonus a second time; we refuse.
    """


class MazeStringWarning(UserWarning):
    """A token of a maze string was accepted but has no effect on the maze.

    The reference library silently ignores such tokens (``l.25`` without any
    ``L`` sign, ``L.25`` without ``l``); we keep accepting them, with the same
    maze as result, but say so.
    """

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


class ActionError(AmazeError):
    """An action given to an agent cannot be applied.

    A discrete action that is not one of 0..3, a continuous action that is not
    two real numbers per agent, or a continuous action holding a NaN or an
    infinity: such a value is always a bug upstream (a diverged network, say),
    which silently replacing it would hide. Finite accelerations outside the
    action space [-1, 1] are not errors: they are clipped
    (``docs/reference-behaviour.md`` §4.4).
    """


class OptionError(AmazeError):
    """An option of a simulation, engine or environment is of the wrong type or out of range.

    A deadline factor, a number of agents, reset options, a render mode...:
    the message names the option and the value.
    """


class EpisodeEndedError(AmazeError):
    """An agent was stepped after its episode reached the goal or the deadline.

    The reference library added the finish bonus a second time; we refuse.
    """


class MazeStringWarning(UserWarning):
    """A token of a maze string, or part of one, was accepted but has no effect on the maze.

    The reference library silently ignores such tokens (``l.25`` without any
    ``L`` sign, ``L.25`` without ``l``) and whatever follows the flags ``U``
    and ``R`` (``Ux`` is ``U``, ``UR`` is ``U`` alone); we keep accepting them,
    with the same maze as result, but say so.
    """


def one_line(error: BaseException) -> str:
    """The first line of an error's message, for reports of one line.

    An ``OSError`` reads ``"<reason>: <file>"``; an error without a message
    is named by its class.
    """
    if isinstance(error, OSError) and error.filename is not None:
        return f"{error.strerror or type(error).__name__}: {error.filename}"
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__

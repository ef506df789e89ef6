"""Checks of user-given values: one place for "is this a positive integer?" and "is this JSON?".

Configs, constructors and command-line options all take numbers from users.
These helpers check one value and return it (typed), or raise the caller's
error class (a :class:`ValueError` subclass) with a message naming the value,
as the project's error contract asks. Booleans are never numbers here
(``True`` is an ``int`` in Python, never a meaningful count), and non-finite
floats are refused unless ``finite=False``.

:func:`parse_json` reads a JSON document from a file or a request the same
way everywhere: any text (invalid UTF-8, a BOM, nesting deep enough to exhaust
Python's recursion) ends in the caller's error naming where it came from.
"""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Iterable
from numbers import Integral, Real
from typing import Any

__all__ = [
    "MAX_HIDDEN_LAYERS",
    "MAX_JSON_DEPTH",
    "MAX_LAYER_WIDTH",
    "MAX_ROLLOUT_BYTES",
    "MAX_ROLLOUT_SAMPLES",
    "check_integer",
    "check_layer_widths",
    "check_number",
    "check_rollout_size",
    "closest",
    "nests_within",
    "parse_json",
]

#: Deepest nesting of arrays and objects :func:`parse_json` accepts. The
#: project's files nest a few levels; a document nested hundreds deep would
#: exhaust Python's recursion later, in whatever code walks it.
MAX_JSON_DEPTH = 100
#: Widest hidden layer and most hidden layers a network of any trainer may ask for:
#: bounds checked before a network is built, so that no config or file can make
#: the program allocate without limit (the networks of the paper have two layers of 64).
MAX_LAYER_WIDTH = 4096
MAX_HIDDEN_LAYERS = 16
#: The most samples (``n_steps * n_envs``) one RL rollout may hold, in any
#: trainer or file: the rollout is allocated whole, so its size is bounded
#: before it exists. Far above common setups (SB3's default is 2,048 x 4);
#: about 1 GiB of observations for DD and H15 robots.
MAX_ROLLOUT_SAMPLES = 1 << 22
#: The most bytes of observations one rollout may hold (as float32s, as SB3's
#: buffer stores them): 2**22 samples of DD or H15, fewer of wider retinas.
MAX_ROLLOUT_BYTES = 1 << 32


def _integer_kind(minimum: int | None, maximum: int | None) -> str:
    """ "a positive integer", "an integer in [2, 100]"...: what the value should have been."""
    if maximum is None:
        if minimum is None:
            return "an integer"
        if minimum in (0, 1):
            return "a non-negative integer" if minimum == 0 else "a positive integer"
        return f"an integer >= {minimum}"
    if minimum is None:
        return f"an integer <= {maximum}"
    return f"an integer in [{minimum}, {maximum}]"


def check_integer(
    name: str,
    value: object,
    *,
    minimum: int | None = None,
    maximum: int | None = None,
    error: type[ValueError] = ValueError,
) -> int:
    """``value`` as an ``int`` if it is an integer (numpy's too) within the bounds.

    Raises ``error("<name> <value> is not a positive integer")`` (or the like) otherwise.

    >>> check_integer("seed", 7, minimum=0)
    7
    >>> check_integer("seed", -1, minimum=0)
    Traceback (most recent call last):
    ValueError: seed -1 is not a non-negative integer
    """
    number = None if isinstance(value, bool) or not isinstance(value, Integral) else int(value)
    if (
        number is None
        or (minimum is not None and number < minimum)
        or (maximum is not None and number > maximum)
    ):
        raise error(f"{name} {value!r} is not {_integer_kind(minimum, maximum)}")
    return number


def check_number(
    name: str,
    value: object,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    strict_minimum: bool = False,
    finite: bool = True,
    error: type[ValueError] = ValueError,
) -> float:
    """``value`` as a ``float`` if it is a real number (not a bool) within the bounds.

    ``strict_minimum`` excludes ``minimum`` itself (``> 0`` rather than ``>= 0``);
    ``finite`` refuses NaN and infinities (NaN is always refused).
    """
    if isinstance(value, bool) or not isinstance(value, Real):
        raise error(f"{name} {value!r} is not a number")
    try:
        number = float(value)
    except OverflowError:  # an integer too large for a float
        number = math.inf if value > 0 else -math.inf
    if math.isnan(number) or (finite and math.isinf(number)):
        raise error(f"{name} {value!r} is not a finite number")
    low_ok = minimum is None or (number > minimum if strict_minimum else number >= minimum)
    high_ok = maximum is None or number <= maximum
    if not (low_ok and high_ok):
        if minimum is not None and maximum is not None:
            opening = "(" if strict_minimum else "["
            bounds = f"in {opening}{minimum}, {maximum}]"
        elif minimum is not None:
            bounds = f"> {minimum}" if strict_minimum else f">= {minimum}"
        else:
            bounds = f"<= {maximum}"
        raise error(f"{name} {value!r} is not a number {bounds}")
    return number


def closest(name: object, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the known name closest to a mistyped ``name``, or ``""``.

    For the messages that refuse an unknown key: a typo is named with what it
    was meant to be.

    >>> closest("budget_step", ["budget_steps", "budget_seconds", "seed"])
    " (did you mean 'budget_steps'?)"
    >>> closest("xyz", ["seed"])
    ''
    """
    if not isinstance(name, str):
        return ""
    match = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean {match[0]!r}?)" if match else ""


def check_layer_widths(
    name: str, value: object, *, error: type[ValueError] = ValueError
) -> tuple[int, ...]:
    """``value`` as a tuple of hidden-layer widths, each in [1, :data:`MAX_LAYER_WIDTH`],
    at most :data:`MAX_HIDDEN_LAYERS` of them; ``error`` naming ``name`` otherwise.

    >>> check_layer_widths("net_arch", [64, 64])
    (64, 64)
    >>> check_layer_widths("net_arch", [1000000])
    Traceback (most recent call last):
    ValueError: net_arch layer 1000000 is not an integer in [1, 4096]
    """
    if isinstance(value, str | bytes) or not isinstance(value, list | tuple):
        raise error(f"{name} {value!r} is not a list of layer widths")
    if len(value) > MAX_HIDDEN_LAYERS:
        raise error(f"{name} has {len(value)} layers, more than {MAX_HIDDEN_LAYERS}")
    return tuple(
        check_integer(f"{name} layer", width, minimum=1, maximum=MAX_LAYER_WIDTH, error=error)
        for width in value
    )


def check_rollout_size(
    n_steps: int, n_envs: int, observation_size: int, *, error: type[ValueError] = ValueError
) -> int:
    """The samples of a rollout (``n_steps * n_envs``), within the bounds; ``error`` otherwise.

    At most :data:`MAX_ROLLOUT_SAMPLES` samples, and at most
    :data:`MAX_ROLLOUT_BYTES` of observations of ``observation_size`` numbers
    each (stored as float32): what a rollout buffer allocates, bounded before
    it is built.

    >>> check_rollout_size(2048, 4, 8)
    8192
    >>> check_rollout_size(4096, 256, 65 * 65)
    Traceback (most recent call last):
    ValueError: a rollout of n_steps 4096 x n_envs 256 = 1,048,576 samples of 4225 inputs ...
    """
    samples = n_steps * n_envs
    if samples > MAX_ROLLOUT_SAMPLES:
        raise error(
            f"a rollout of n_steps {n_steps} x n_envs {n_envs} = {samples:,} samples is more"
            f" than {MAX_ROLLOUT_SAMPLES:,}"
        )
    needed = samples * observation_size * 4
    if needed > MAX_ROLLOUT_BYTES:
        raise error(
            f"a rollout of n_steps {n_steps} x n_envs {n_envs} = {samples:,} samples of"
            f" {observation_size} inputs needs {needed:,} bytes of observations, more than"
            f" {MAX_ROLLOUT_BYTES:,}"
        )
    return samples


def parse_json(
    text: str | bytes,
    what: str,
    *,
    error: type[ValueError] = ValueError,
    max_depth: int = MAX_JSON_DEPTH,
) -> Any:
    """The value of the JSON document ``text``; ``error`` naming ``what`` otherwise.

    ``what`` says where the text came from (``"summary 'runs/x/summary.json'"``).
    Bytes must be UTF-8 (a leading BOM is refused, as JSON forbids it);
    nesting deeper than ``max_depth`` (``[`` x 100000) is refused like any
    other bad document.

    >>> parse_json('{"seed": [1, 2]}', "config")
    {'seed': [1, 2]}
    >>> parse_json("[[[1]]]", "config", max_depth=2)
    Traceback (most recent call last):
    ValueError: config nests arrays or objects more than 2 deep
    """
    if isinstance(text, bytes | bytearray):
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError as problem:
            raise error(
                f"{what} is not UTF-8 text ({problem.reason} at byte {problem.start})"
            ) from None
    if text.startswith("\ufeff"):
        raise error(f"{what} starts with a byte-order mark, which JSON does not allow")
    try:
        value = json.loads(text)
    except ValueError as problem:  # JSONDecodeError, or an integer of over 4300 digits
        raise error(f"{what} is not JSON: {problem}") from None
    except RecursionError:
        value = None
    else:
        if nests_within(value, max_depth):
            return value
    raise error(f"{what} nests arrays or objects more than {max_depth} deep")


def nests_within(value: Any, limit: int) -> bool:
    """Whether ``value`` (parsed JSON or TOML) nests lists and dicts at most ``limit`` deep.

    Walked without recursion, so that any depth is measured safely.
    """
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            if depth > limit:
                return False
            stack.extend((child, depth + 1) for child in item)
    return True

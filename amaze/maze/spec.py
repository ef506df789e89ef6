"""Maze specifications and the maze-string grammar.

A :class:`MazeSpec` holds everything needed to generate a maze (size, seed,
start corner, signs and their probabilities). It reads and prints the reference
library's maze strings (``docs/reference-behaviour.md`` §2), e.g.
``M4_20x20_C1_l.25_L.25_t.5_T.5``:

========  ===============================================================
token     meaning
========  ===============================================================
``M4``    seed 4 (any non-negative integer)
``20x20`` width x height, each in 2..100 (default 10x10)
``SE``    start corner (``SW`` default, ``SE``, ``NE``, ``NW``)
``U``     unicursive: every side branch of the solution is walled off
``R``     not rotated: generate from the real corner instead of rotating
          the south-west maze
``C1``    a clue sign type (``C<sign>``, see :mod:`amaze.maze.signs`)
``l.25``  lure probability (of the path cells that are not intersections)
``L.25``  a lure sign type
``t.5``   trap probability (of the intersections)
``T.5``   a trap sign type
========  ===============================================================

Tokens are separated by ``_`` or spaces, in any order; a later token overrides
an earlier one (``5x5_3x3`` is 3x3) and sign tokens accumulate. Everything up to
the last ``__`` is ignored (a name prefix).

Strings the reference generates a maze from give the same maze here; bad
input is treated otherwise: a malformed token (a negative seed too) raises
:class:`~amaze.errors.MazeStringError` (a ``ValueError``) naming the token, and
tokens without effect (``l.25`` without lure signs) or with trailing characters
(``Ux``, ``UR``) are accepted but emit a :class:`~amaze.errors.MazeStringWarning`
(the differences are listed in ``docs/reference-behaviour.md`` §10).

A string without a seed gets a fresh random one (from the operating system's
entropy, not the clock, so two mazes made in the same millisecond differ); the
canonical string printed by :meth:`MazeSpec.to_string` always carries it, so
the maze can be regenerated. Canonical printing follows the reference
(``l0.25``/``t0.5``, ``C.5``, ``Cpoint-.5``) except that numbers keep all
their digits (``C.125``, where the reference printed the lossy ``C.12``).
"""

from __future__ import annotations

import dataclasses
import re
import secrets
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from enum import IntEnum

from amaze.errors import MazeStringError, MazeStringWarning
from amaze.maze.signs import Sign, as_sign, format_value
from amaze.validation import check_integer, check_number

MIN_SIZE, MAX_SIZE = 2, 100
_SIZE_TOKEN = re.compile(r"[0-9]+x[0-9]+")
_CORNER_TOKEN = re.compile(r"[SN][WE]")
_SEED_RANGE = 2**31


class StartLocation(IntEnum):
    """The corner the agent starts from; the goal is in the opposite corner."""

    SOUTH_WEST = 0
    SOUTH_EAST = 1
    NORTH_EAST = 2
    NORTH_WEST = 3

    @property
    def shorthand(self) -> str:
        """``SW``, ``SE``, ``NE`` or ``NW``."""
        first, second = self.name.split("_")
        return first[0] + second[0]

    @classmethod
    def from_shorthand(cls, text: str) -> StartLocation:
        """Parse ``SW``, ``SE``, ``NE`` or ``NW``."""
        for location in cls:
            if location.shorthand == text:
                return location
        raise MazeStringError(f"unknown start corner '{text}' (expected SW, SE, NE or NW)")

    def corner(self, width: int, height: int) -> tuple[int, int]:
        """The cell of this corner in a ``width`` x ``height`` maze."""
        i = 0 if self in (StartLocation.SOUTH_WEST, StartLocation.NORTH_WEST) else width - 1
        j = 0 if self in (StartLocation.SOUTH_WEST, StartLocation.SOUTH_EAST) else height - 1
        return i, j


def random_seed() -> int:
    """A fresh seed in ``[0, 2**31)`` from the operating system's entropy."""
    return secrets.randbelow(_SEED_RANGE)


@dataclass(frozen=True)
class MazeSpec:
    """Everything needed to generate a maze; immutable and hashable.

    ``seed=None`` draws a fresh random seed at construction (the canonical
    string then records it). The lure (trap) probability and the lure (trap)
    sign list are coupled as in the reference: if either is missing or zero,
    no lure (trap) is placed and the probability is normalised to ``None``.
    """

    width: int = 10
    height: int = 10
    seed: int | None = None
    start: StartLocation = StartLocation.SOUTH_WEST
    rotated: bool = True
    unicursive: bool = False
    clue: tuple[Sign, ...] = ()
    lure: tuple[Sign, ...] = ()
    p_lure: float | None = None
    trap: tuple[Sign, ...] = ()
    p_trap: float | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen dataclass: normalise in place once
        for name in ("width", "height"):
            size = check_integer(
                name, getattr(self, name), minimum=MIN_SIZE, maximum=MAX_SIZE, error=MazeStringError
            )
            set_(self, name, size)
        if self.seed is None:
            set_(self, "seed", random_seed())
        else:
            set_(self, "seed", check_integer("seed", self.seed, minimum=0, error=MazeStringError))
        try:
            set_(self, "start", StartLocation(self.start))
        except ValueError:
            raise MazeStringError(f"start {self.start!r} is not a StartLocation") from None
        for name in ("rotated", "unicursive"):
            if not isinstance(getattr(self, name), bool):
                raise MazeStringError(f"{name} {getattr(self, name)!r} is not a bool")
        for name in ("clue", "lure", "trap"):
            set_(self, name, _as_signs(name, getattr(self, name)))
        for name in ("p_lure", "p_trap"):
            value = getattr(self, name)
            if value is None:
                continue
            set_(self, name, check_number(name, value, minimum=0, maximum=1, error=MazeStringError))
        # Couplings of the reference (docs/reference-behaviour.md §2.4).
        if not self.p_lure or not self.lure:
            set_(self, "p_lure", None)
            set_(self, "lure", ())
        if not self.p_trap or not self.trap:
            set_(self, "p_trap", None)
            set_(self, "trap", ())

    # -- strings -----------------------------------------------------------

    @classmethod
    def from_string(cls, text: str, **overrides: object) -> MazeSpec:
        """Parse a maze string; keyword arguments override the parsed fields.

        >>> spec = MazeSpec.from_string("M4_20x20_C1_l.25_L.25_t.5_T.5")
        >>> spec.seed, spec.width, spec.p_lure, spec.clue
        (4, 20, 0.25, (Sign(shape='arrow', value=1.0),))
        >>> str(MazeSpec.from_string("M4_20x20_C1", width=12))
        'M4_12x20_C1'
        """
        if not isinstance(text, str):
            raise MazeStringError(f"a maze string must be a str, not {type(text).__name__}")
        values: dict[str, object] = {}
        signs: dict[str, list[Sign]] = {"clue": [], "lure": [], "trap": []}
        set_tokens: dict[str, str] = {}
        tokens = text.split("__")[-1].replace("_", " ").split()
        for token in tokens:
            _parse_token(token, values, signs, set_tokens)
        values.update({name: tuple(lst) for name, lst in signs.items()})
        values.update(overrides)
        try:
            spec = cls(**values)  # type: ignore[arg-type]
        except MazeStringError as error:
            raise MazeStringError(f"maze string '{text}': {error}") from None
        _warn_unused_tokens(text, spec, set_tokens, signs)
        _warn_flag_tails(text, tokens)
        return spec

    def to_string(self, simplify: bool = False) -> str:
        """The canonical maze string; ``simplify`` drops clues and traps of unicursive mazes."""
        tokens = [f"M{self.seed}", f"{self.width}x{self.height}"]
        if self.start != StartLocation.SOUTH_WEST:
            tokens.append(self.start.shorthand)
        if self.unicursive:
            tokens.append("U")
        if not self.rotated:
            tokens.append("R")
        drop = simplify and self.unicursive
        if not drop:
            tokens.extend(f"C{sign}" for sign in self.clue)
        if self.p_lure and self.lure:
            tokens.append(f"l{format_value(self.p_lure)}")
            tokens.extend(f"L{sign}" for sign in self.lure)
        if not drop and self.p_trap and self.trap:
            tokens.append(f"t{format_value(self.p_trap)}")
            tokens.extend(f"T{sign}" for sign in self.trap)
        return "_".join(tokens)

    def __str__(self) -> str:
        return self.to_string()

    # -- variants ----------------------------------------------------------

    def where(self, **changes: object) -> MazeSpec:
        """A copy with some fields changed (validated like a new spec)."""
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.init}
        values.update(changes)
        return MazeSpec(**values)  # type: ignore[arg-type]

    def in_shape(self, shape: str) -> MazeSpec:
        """A copy whose signs are all drawn in ``shape``, with their kinds and lightnesses.

        ``M1_10x10_C1_L.25`` in ``star`` is ``M1_10x10_Cstar-1_Lstar-.25``: the
        same maze, with other images on its signs (for H robots).
        """
        return self.where(
            **{
                kind: tuple(Sign(shape, sign.value) for sign in getattr(self, kind))
                for kind in ("clue", "lure", "trap")
            }
        )

    def all_rotations(self) -> list[MazeSpec]:
        """The spec started from each corner, in the reference's order (NW, NE, SW, SE)."""
        order = (
            StartLocation.NORTH_WEST,
            StartLocation.NORTH_EAST,
            StartLocation.SOUTH_WEST,
            StartLocation.SOUTH_EAST,
        )
        return [self.where(start=start) for start in order]


def _as_signs(name: str, signs: object) -> tuple[Sign, ...]:
    if isinstance(signs, (str, Sign)) or not isinstance(signs, Iterable):
        raise MazeStringError(f"{name} must be a sequence of signs, not {signs!r}")
    return tuple(as_sign(sign, f"{name} sign", MazeStringError) for sign in signs)


def _parse_token(
    token: str,
    values: dict[str, object],
    signs: dict[str, list[Sign]],
    set_tokens: dict[str, str],
) -> None:
    head, tail = token[0], token[1:]
    try:
        if head == "M":
            seed = int(tail)
            if seed < 0:
                raise MazeStringError(f"seed token '{token}': the seed must not be negative")
            values["seed"] = seed
        elif head == "U":
            values["unicursive"] = True
        elif head == "R":
            values["rotated"] = False
        elif head in "CLT":
            kind = {"C": "clue", "L": "lure", "T": "trap"}[head]
            signs[kind].append(Sign.from_string(tail))
            set_tokens.setdefault(kind, token)
        elif head in "lt":
            if tail:
                name = "p_lure" if head == "l" else "p_trap"
                values[name] = float(tail)
                set_tokens[name] = token
        elif _SIZE_TOKEN.match(token):
            parts = token.split("x")
            if len(parts) != 2:
                raise MazeStringError(f"malformed size token '{token}' (expected WxH)")
            values["width"], values["height"] = (int(part) for part in parts)
        elif _CORNER_TOKEN.match(token):
            values["start"] = StartLocation.from_shorthand(token)
        else:
            raise MazeStringError(f"unknown or malformed token '{token}'")
    except MazeStringError as error:
        if f"'{token}'" in str(error):
            raise
        raise MazeStringError(f"token '{token}': {error}") from None
    except ValueError as error:  # int()/float() of a malformed tail, or a bad sign
        raise MazeStringError(f"malformed token '{token}': {error}") from None


#: The flag tokens whose first letter alone counts: what follows is ignored (reference §2.2).
_FLAGS = ("U", "R")


def _flag_advice(token: str) -> str:
    """What to write instead of a flag token with a tail.

    ``UR`` or ``U5x5``: two tokens run together (``U_R``, ``U_5x5``), when the
    tail reads as a token; otherwise the flag alone (``Ux``: ``U``).
    """
    head, tail = token[0], token[1:]
    try:
        _parse_token(tail, {}, {"clue": [], "lure": [], "trap": []}, {})
    except MazeStringError:
        return f"write '{head}' alone"
    return f"did you mean '{head}_{tail}' (two tokens)?"


def _warn_flag_tails(text: str, tokens: Iterable[str]) -> None:
    """Warn about ``U``/``R`` tokens with trailing characters, read as the flag alone."""
    for token in tokens:
        if token[0] in _FLAGS and len(token) > 1:
            warnings.warn(
                f"maze string '{text}': token '{token}' is read as '{token[0]}' (the reference"
                f" ignores what follows {token[0]}); {_flag_advice(token)}",
                MazeStringWarning,
                stacklevel=3,
            )


def _warn_unused_tokens(
    text: str, spec: MazeSpec, set_tokens: dict[str, str], signs: dict[str, list[Sign]]
) -> None:
    unused = []
    if "p_lure" in set_tokens and spec.p_lure is None and not signs["lure"]:
        unused.append(f"'{set_tokens['p_lure']}' (no lure sign type)")
    if signs["lure"] and "p_lure" not in set_tokens:
        unused.append(f"'{set_tokens['lure']}' (no lure probability l)")
    if "p_trap" in set_tokens and spec.p_trap is None and not signs["trap"]:
        unused.append(f"'{set_tokens['p_trap']}' (no trap sign type)")
    if signs["trap"] and "p_trap" not in set_tokens:
        unused.append(f"'{set_tokens['trap']}' (no trap probability t)")
    if unused:
        warnings.warn(
            f"maze string '{text}': token(s) without effect: {', '.join(unused)}",
            MazeStringWarning,
            stacklevel=3,
        )

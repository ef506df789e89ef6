"""Signs: the visual cues placed in maze cells (clues, lures and traps).

A :class:`Sign` is a *type* of sign, a shape and a lightness value in ]0, 1]
(the value a discrete agent perceives). Which shapes exist is kept in a small
registry: the reference's built-in shapes, plus custom PNG images that a user
registers explicitly (a file or a folder) or lists in the ``AMAZE_CUSTOM_SIGNS``
environment variable (paths separated by ``os.pathsep``). Unlike the reference,
nothing is looked up relative to the current working directory, and importing
this module reads and writes no file.

Sign specifications follow the reference grammar (``docs/reference-behaviour.md`` §2.3):
``1`` (an arrow of lightness 1), ``.5``, ``point`` (lightness 0.5),
``point-.25``. They print back in the shortest form that parses to the same
sign: ``arrow`` is omitted, leading zeros are stripped (``.25``), and unlike the
reference no digit is lost (``.125`` stays ``.125``; the reference prints ``.12``).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any, NamedTuple

from amaze.errors import SignError
from amaze.maze.directions import Cell, Direction
from amaze.validation import check_number

#: Shapes drawn by the library itself (the reference's built-ins), sorted.
BUILTIN_SHAPES: tuple[str, ...] = (
    "alien",
    "arrow",
    "error",
    "forbidden",
    "point",
    "rarrow",
    "star",
    "warning",
)
DEFAULT_SHAPE = "arrow"
DEFAULT_LIGHTNESS = 0.5
CUSTOM_SIGNS_ENV = "AMAZE_CUSTOM_SIGNS"

_SEPARATOR = "-"
_CUSTOM_NAME = re.compile(r"[a-z][a-z0-9]*")


class SignKind(StrEnum):
    """What a placed sign tells the agent."""

    CLUE = "clue"
    """Helpful: points the correct way at an intersection."""
    LURE = "lure"
    """Unhelpful: points a wrong way in a corridor of the solution path."""
    TRAP = "trap"
    """Deceitful: points a wrong, open way at an intersection."""


class _ShapeRegistry:
    """Known sign shapes: the built-ins and the registered custom images."""

    def __init__(self) -> None:
        self._custom: dict[str, Path] = {}
        self._env_loaded: str | None = None

    def _load_environment(self) -> None:
        value = os.environ.get(CUSTOM_SIGNS_ENV, "")
        if value == self._env_loaded:
            return
        self._env_loaded = value
        for entry in filter(None, value.split(os.pathsep)):
            self.register(entry)

    def register(self, path: str | os.PathLike) -> list[str]:
        """Register a PNG file, or every PNG file of a folder; return the new names."""
        path = Path(path).expanduser()
        if path.is_dir():
            files = sorted(path.glob("*.png"))
        elif path.is_file():
            files = [path]
        else:
            raise SignError(f"custom sign path '{path}' is neither a PNG file nor a folder")
        names = []
        for file in files:
            if file.suffix.lower() != ".png":
                raise SignError(f"custom sign '{file}' is not a .png file")
            name = file.stem.lower()
            if not _CUSTOM_NAME.fullmatch(name):
                raise SignError(
                    f"custom sign file '{file}': its name '{file.stem}' must be a letter"
                    " followed by letters or digits (it is used in maze strings)"
                )
            if name in BUILTIN_SHAPES:
                raise SignError(
                    f"custom sign file '{file}' would shadow the built-in shape '{name}'"
                )
            self._custom[name] = file.resolve()
            names.append(name)
        return names

    def custom_path(self, name: str) -> Path | None:
        self._load_environment()
        return self._custom.get(name)

    def names(self) -> list[str]:
        self._load_environment()
        return sorted(set(BUILTIN_SHAPES) | set(self._custom))

    def clear(self) -> None:
        self._custom.clear()
        self._env_loaded = None


_REGISTRY = _ShapeRegistry()


def register_custom_signs(path: str | os.PathLike) -> list[str]:
    """Make the PNG image(s) at ``path`` (a file or a folder) usable as sign shapes.

    A file ``biomorph.png`` becomes the shape ``biomorph`` (``Cbiomorph-.5`` in a
    maze string). Images are square, or four square frames stacked vertically
    (one per direction E, N, W, S); colours are converted to gray levels.
    Returns the registered shape names.
    """
    return _REGISTRY.register(path)


def clear_custom_signs() -> None:
    """Forget every registered custom shape (the environment variable is re-read later)."""
    _REGISTRY.clear()


def custom_sign_path(shape: str) -> Path | None:
    """The image file of a custom shape, or ``None`` for a built-in or unknown shape."""
    return _REGISTRY.custom_path(shape)


def known_shapes() -> list[str]:
    """All usable shape names (built-in and registered custom), sorted."""
    return _REGISTRY.names()


def format_value(value: float) -> str:
    """Print a number in the shortest form that reads back to the same float.

    ``1.0 -> '1'``, ``0.25 -> '0.25'``; for numbers with at most two significant
    digits this is what the reference's ``f"{v:.2g}"`` prints.
    """
    text = repr(float(value))
    if text.endswith(".0"):
        text = text[:-2]
    return text


@dataclass(frozen=True)
class Sign:
    """A type of sign: a shape name and a lightness value in ]0, 1]."""

    shape: str = DEFAULT_SHAPE
    value: float = DEFAULT_LIGHTNESS

    def __post_init__(self) -> None:
        if not isinstance(self.shape, str):
            raise SignError(f"sign shape must be a string, not {self.shape!r}")
        shape = self.shape.lower()
        if shape not in known_shapes():
            raise SignError(
                f"unknown sign shape '{self.shape}' (known: {', '.join(known_shapes())};"
                f" register custom PNG images with register_custom_signs or {CUSTOM_SIGNS_ENV})"
            )
        value = check_number(
            "sign value", self.value, minimum=0, strict_minimum=True, maximum=1, error=SignError
        )
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "value", value)

    @classmethod
    def from_string(cls, spec: str) -> Sign:
        """Parse a sign specification: ``VALUE``, ``SHAPE`` or ``SHAPE-VALUE``."""
        tokens = spec.split(_SEPARATOR)
        if len(tokens) == 1:
            try:
                return cls(DEFAULT_SHAPE, _parse_float(tokens[0], spec))
            except _NotANumber:
                return cls(tokens[0], DEFAULT_LIGHTNESS)
        if len(tokens) == 2:
            try:
                value = _parse_float(tokens[1], spec)
            except _NotANumber:
                raise SignError(
                    f"sign '{spec}': '{tokens[1]}' is not a valid lightness value"
                ) from None
            return cls(tokens[0], value)
        raise SignError(f"malformed sign '{spec}': expected VALUE, SHAPE or SHAPE-VALUE")

    def to_string(self) -> str:
        """The canonical specification (``arrow`` omitted, leading zero stripped)."""
        value = format_value(self.value).lstrip("0")
        return value if self.shape == DEFAULT_SHAPE else f"{self.shape}{_SEPARATOR}{value}"

    def __str__(self) -> str:
        return self.to_string()


def as_sign(value: object, what: str, error: type[ValueError]) -> Sign:
    """``value`` as a :class:`Sign`: a sign, or a sign string parsed with :meth:`Sign.from_string`.

    Anything else raises ``error`` naming ``what`` (e.g. ``"clue sign"``) and the value.
    """
    if isinstance(value, str):
        try:
            return Sign.from_string(value)
        except SignError as problem:
            raise error(f"{what} '{value}': {problem}") from None
    if not isinstance(value, Sign):
        raise error(f"{what} {value!r} is neither a Sign nor a sign string")
    return value


class _NotANumber(Exception):
    pass


def _parse_float(text: str, spec: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise _NotANumber from None


class PlacedSign(NamedTuple):
    """One sign in one cell of the solution path (a light immutable record)."""

    kind: SignKind
    #: Index of the sign type in the spec's ``clue``/``lure``/``trap`` list.
    sign_index: int
    sign: Sign
    #: Index of the cell in ``Maze.solution``.
    solution_index: int
    cell: Cell
    #: Where the sign points.
    direction: Direction
    #: The correct move from this cell (towards the goal).
    truth: Direction
    #: True for a trap at a four-way crossing, where the reference library picks
    #: one of the two wrong open directions by string-hash order (it depends on
    #: ``PYTHONHASHSEED``). We pick deterministically (see amaze.maze.generation).
    reference_undefined: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The ``amaze inspect --json`` form of this sign."""
        return {
            "kind": self.kind.value,
            "cell": list(self.cell),
            "direction": int(self.direction),
            "truth": int(self.truth),
            "value": self.sign.value,
            "shape": self.sign.shape,
        }

"""Designing a maze on the page: its fields as form controls, and what it is.

The page never parses maze strings itself: it sends a string (typed) or the
form's fields (a control changed) and gets back a :func:`maze_card`, the
canonical string, its fields for the controls, and the figures a curator
judges a maze by (class, Surprisingness, Deceptiveness, path length,
intersections, signs, difficulty) with how it differs from the maze the
agent trained on last. Bad input raises :class:`DesignError` naming the
field or the string's bad token, shown inline next to the field.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from amaze.curriculum.difficulty import difficulty_profile
from amaze.curriculum.distance import maze_distance
from amaze.curriculum.genome import new_seed
from amaze.errors import AmazeError, MazeStringWarning, one_line
from amaze.maze.maze import Maze
from amaze.maze.metrics import compute_metrics
from amaze.maze.signs import Sign
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec, StartLocation
from amaze.validation import check_integer, check_number

__all__ = [
    "MAX_STRING_LENGTH",
    "DesignError",
    "maze_card",
    "maze_fields",
    "spec_from_fields",
    "strict_maze",
    "with_new_seed",
]

#: Longest maze string the page accepts (the longest sensible one is under 100 characters).
MAX_STRING_LENGTH = 300
#: The sign kinds, as the form names them, with their spec fields (signs, probability).
SIGN_KINDS = {"clue": ("clue", None), "lure": ("lure", "p_lure"), "trap": ("trap", "p_trap")}
CORNERS = tuple(corner.shorthand for corner in StartLocation)


class DesignError(AmazeError):
    """A maze the page sent that cannot be built: the message names the field or token."""


def _missing(value: Any, what: str) -> None:
    """A :class:`DesignError` saying ``what`` is missing when ``value`` is ``None`` (JSON's
    ``null``, or no key): the page shows the message, and Python's ``None`` means nothing there."""
    if value is None:
        raise DesignError(f"{what} is missing")


def parse_maze(text: Any) -> tuple[MazeSpec, list[str]]:
    """The spec of a maze string and the parser's warnings (tokens without effect)."""
    _missing(text, "the maze string")
    if not isinstance(text, str):
        raise DesignError(f"maze string {text!r} is not text")
    if len(text) > MAX_STRING_LENGTH:
        raise DesignError(f"maze string of {len(text)} characters (at most {MAX_STRING_LENGTH})")
    if not text.strip():
        raise DesignError("the maze string is empty")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MazeStringWarning)
        try:
            spec = MazeSpec.from_string(text)
        except (ValueError, TypeError) as problem:
            raise DesignError(one_line(problem)) from None
    notes = [one_line(w.message) for w in caught if issubclass(w.category, MazeStringWarning)]
    return spec, notes


#: A parser message that names the token it is about.
_TOKEN = re.compile(r"token '([^']*)'")
#: A size token (``7x7``): the parser's size errors name the side, not the token.
_SIZE = re.compile(r"^\d+x\d+$")
#: Most bad tokens a string is searched for (a string has a handful of tokens).
_MAX_PROBLEMS = 32


def _without_prefix(message: str) -> str:
    """A parser message without its ``maze string '...': `` prefix."""
    return re.sub(r"^maze string '.*?': ", "", message)


def strict_maze(text: Any) -> MazeSpec:
    """The spec of a maze string in which every token has its effect; else every bad token named.

    The page refuses what the parser only warns of (a token without effect,
    such as ``l.25`` without a lure sign, or the tail of ``Ux``): a person who
    typed it meant something the agent would not get. A string with several
    bad tokens names them all (the parser stops at its first error: the
    token it names is set aside and the rest parsed again).
    """
    _missing(text, "the maze string")
    if not isinstance(text, str):
        raise DesignError(f"maze string {text!r} is not text")
    tokens = text.strip().split("_")
    problems: list[str] = []
    spec: MazeSpec | None = None
    while len(problems) < _MAX_PROBLEMS:
        try:
            spec, notes = parse_maze("_".join(tokens) if tokens else text)
        except DesignError as problem:
            message = _without_prefix(str(problem))
            problems.append(message)
            named = _TOKEN.search(message)
            if named and named.group(1) in tokens:
                tokens.remove(named.group(1))
            elif message.startswith(("width", "height")):
                sizes = [t for t in tokens if _SIZE.match(t)]
                if not sizes:
                    break
                tokens.remove(sizes[0])
            else:
                break
            if not tokens:
                break
            continue
        problems += [_without_prefix(note) for note in notes]
        break
    if problems or spec is None:
        raise DesignError("; ".join(problems) or f"maze string {text!r} cannot be read")
    return spec


def maze_fields(spec: MazeSpec) -> dict[str, Any]:
    """The form's controls for ``spec``: size, seed, corner, unicursive, each sign kind.

    A kind with several sign types shows its first one; the others are kept
    as they are by :func:`spec_from_fields`.
    """
    fields: dict[str, Any] = {
        "width": spec.width,
        "height": spec.height,
        "seed": spec.seed,
        "start": spec.start.shorthand,
        "unicursive": spec.unicursive,
    }
    for kind, (signs_field, probability_field) in SIGN_KINDS.items():
        signs: tuple[Sign, ...] = getattr(spec, signs_field)
        fields[kind] = bool(signs)
        fields[f"{kind}_value"] = signs[0].value if signs else 1.0 if kind == "clue" else 0.5
        if probability_field is not None:
            probability = getattr(spec, probability_field)
            fields[f"p_{kind}"] = probability if probability is not None else 0.25
    return fields


def _whole(fields: Mapping[str, Any], name: str, **bounds: int) -> int:
    """The whole number ``fields[name]`` within ``bounds`` (``minimum``, ``maximum``).

    ``10.0`` counts as 10 (a script may send whole numbers as floats); NaN,
    infinities and fractions are refused, naming the field and the value.
    """
    value = fields.get(name)
    _missing(value, name)
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    return check_integer(name, value, error=DesignError, **bounds)


def _fraction(fields: Mapping[str, Any], name: str, label: str) -> float:
    """The finite number ``fields[name]`` in ]0, 1] (a lightness, a probability)."""
    _missing(fields.get(name), label)
    return check_number(
        label, fields.get(name), minimum=0, strict_minimum=True, maximum=1, error=DesignError
    )


def spec_from_fields(fields: Any, base: str | None = None) -> MazeSpec:
    """The spec the form's ``fields`` describe (``base``: the string whose other signs stay)."""
    _missing(fields, "the maze form")
    if not isinstance(fields, Mapping):
        raise DesignError(f"maze fields {fields!r} are not an object")
    kept = parse_maze(base)[0] if base else MazeSpec(seed=0)
    start = fields.get("start")
    _missing(start, "start")
    if start not in CORNERS:
        raise DesignError(f"start {start!r} is not one of {', '.join(CORNERS)}")
    changes: dict[str, Any] = {"start": StartLocation.from_shorthand(start)}
    for name in ("width", "height"):
        changes[name] = _whole(fields, name, minimum=MIN_SIZE, maximum=MAX_SIZE)
    changes["seed"] = _whole(fields, "seed", minimum=0)
    unicursive = fields.get("unicursive")
    _missing(unicursive, "unicursive")
    if not isinstance(unicursive, bool):
        raise DesignError(f"unicursive {unicursive!r} is not true or false")
    changes["unicursive"] = unicursive
    for kind, (signs_field, probability_field) in SIGN_KINDS.items():
        on = fields.get(kind)
        _missing(on, f"{kind} (on or off)")
        if not isinstance(on, bool):
            raise DesignError(f"{kind} {on!r} is not true or false")
        signs: tuple[Sign, ...] = getattr(kept, signs_field)
        if not on:
            changes[signs_field] = ()
            continue
        value = _fraction(fields, f"{kind}_value", f"{kind} lightness")
        first = Sign(signs[0].shape if signs else "arrow", value)
        changes[signs_field] = (first, *signs[1:])
        if probability_field is not None:
            changes[probability_field] = _fraction(fields, f"p_{kind}", f"{kind} probability")
    try:
        return kept.where(**changes)
    except (ValueError, TypeError) as problem:
        raise DesignError(one_line(problem)) from None


def with_new_seed(text: str, rng: np.random.Generator) -> str:
    """``text`` with another seed drawn from ``rng``: new walls, same family."""
    return new_seed(parse_maze(text)[0], rng).to_string()


def _changes(before: MazeSpec, after: MazeSpec) -> list[str]:
    """What differs from ``before`` to ``after``, in words."""
    said = []
    if (before.width, before.height) != (after.width, after.height):
        said.append(f"size {before.width}x{before.height} → {after.width}x{after.height}")
    if before.start != after.start:
        said.append(f"start {before.start.shorthand} → {after.start.shorthand}")
    if before.unicursive != after.unicursive:
        said.append("unicursive" if after.unicursive else "no longer unicursive")
    for kind, (signs_field, probability_field) in SIGN_KINDS.items():
        old, new = getattr(before, signs_field), getattr(after, signs_field)
        if old and not new:
            said.append(f"{kind}s removed")
        elif new and not old:
            said.append(f"{kind}s added")
        elif old and new:
            if old[0].value != new[0].value:
                said.append(f"{kind} lightness {old[0].value:g} → {new[0].value:g}")
            if probability_field is not None:
                p_old, p_new = getattr(before, probability_field), getattr(after, probability_field)
                if p_old != p_new:
                    said.append(f"{kind} probability {p_old:g} → {p_new:g}")
    if before.seed != after.seed and not said:
        said.append("same description, new seed")
    return said or ["the same maze"]


def maze_card(text: str, reference: str | None = None) -> dict[str, Any]:
    """What the page shows of a maze: canonical string, fields, figures, comparison.

    ``reference`` is the maze the agent trained on last (the parent's): the
    card says how this maze differs from it and by how much its difficulty
    (:func:`~amaze.curriculum.difficulty.difficulty_profile`'s score) changes.
    """
    spec, notes = parse_maze(text)
    maze = Maze.generate(spec)
    metrics = compute_metrics(maze)
    profile = difficulty_profile(maze)
    card: dict[str, Any] = {
        "string": spec.to_string(),
        "fields": maze_fields(spec),
        "class": maze.maze_class.label,
        "surprisingness": round(metrics.surprisingness, 4),
        "deceptiveness": round(metrics.deceptiveness, 4),
        "path_length": maze.path_length,
        "intersections": maze.n_intersections,
        "clues": len(maze.clues),
        "lures": len(maze.lures),
        "traps": len(maze.traps),
        "difficulty": round(profile.score(), 3),
        "notes": notes,
    }
    if reference is not None:
        before = parse_maze(reference)[0]
        card["comparison"] = {
            "reference": before.to_string(),
            "changes": _changes(before, spec),
            "difficulty": round(difficulty_profile(before).score(), 3),
            "distance": round(maze_distance(before, spec), 3),
        }
    return card

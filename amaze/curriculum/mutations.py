"""The mutation operators of the maze genome, one per field of the maze string.

Each operator takes a spec and a :class:`numpy.random.Generator` and returns
a mutant that differs only in the field(s) it owns, or its input unchanged
where it cannot change the maze; :class:`SignSet` holds the signs the
operators add. :mod:`amaze.curriculum.genome` gathers them with their bounds
(:class:`~amaze.curriculum.genome.MazeGenome`) and describes them in full.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from types import MappingProxyType
from typing import Any

import numpy as np

from amaze.curriculum.interpolation import LIGHTNESS_DIGITS, PROBABILITY_DIGITS
from amaze.errors import AmazeError
from amaze.maze.maze import Maze
from amaze.maze.signs import Sign, SignKind, as_sign
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec, StartLocation
from amaze.validation import check_integer, check_number

__all__ = [
    "DEFAULT_MIN_SIZE",
    "OPERATOR_FIELDS",
    "SEED_RANGE",
    "Changes",
    "GenomeError",
    "SignSet",
    "add_options",
    "add_signs",
    "as_spec",
    "check_rng",
    "check_sizes",
    "check_step",
    "draw_change",
    "lightness_down",
    "lightness_options",
    "lightness_up",
    "new_seed",
    "new_start",
    "probability_down",
    "probability_options",
    "probability_up",
    "remove_options",
    "remove_signs",
    "size_down",
    "size_options",
    "size_up",
    "start_options",
    "toggle_unicursive",
]

#: Smallest side a mutation produces by default (the interpolation curriculum's trivial start).
DEFAULT_MIN_SIZE = 5
#: Fresh seeds are drawn in ``[0, SEED_RANGE)``, as :func:`amaze.maze.spec.random_seed` draws them.
SEED_RANGE = 2**31

MazeLike = MazeSpec | Maze | str


class GenomeError(AmazeError):
    """Bad arguments for a mutation (bounds, steps, sign kind or operator name)."""


# -- the sign set --------------------------------------------------------------


@dataclass(frozen=True)
class SignSet:
    """The sign of each kind that ``add_<kind>`` puts in a maze, with its probability.

    The default is the paper's training maze (``C1``, ``L.25``, ``T.5``,
    ``l.25``, ``t.5``): full-lightness clues, quarter-lightness lures,
    half-lightness traps. Signs may be given as :class:`~amaze.maze.signs.Sign`
    or as sign strings (``"point-.5"``).
    """

    # Built when a SignSet is made, not at import: a Sign looks up the shape
    # registry, which reads AMAZE_CUSTOM_SIGNS.
    clue: Sign = field(default_factory=lambda: Sign("arrow", 1.0))
    lure: Sign = field(default_factory=lambda: Sign("arrow", 0.25))
    trap: Sign = field(default_factory=lambda: Sign("arrow", 0.5))
    p_lure: float = 0.25
    p_trap: float = 0.5

    def __post_init__(self) -> None:
        for kind in SignKind:
            sign = as_sign(getattr(self, kind.value), f"sign set: {kind.value} sign", GenomeError)
            object.__setattr__(self, kind.value, sign)
        for name in ("p_lure", "p_trap"):
            value = check_number(
                f"sign set {name}",
                getattr(self, name),
                minimum=0,
                strict_minimum=True,
                maximum=1,
                error=GenomeError,
            )
            object.__setattr__(self, name, value)

    @classmethod
    def of(cls, maze: MazeLike) -> SignSet:
        """The signs of ``maze``: its first sign of each kind (the default for a kind it lacks)."""
        spec = as_spec(maze)
        values: dict[str, Any] = {}
        for kind in SignKind:
            signs = getattr(spec, kind.value)
            if signs:
                values[kind.value] = signs[0]
        for name in ("p_lure", "p_trap"):
            if getattr(spec, name):
                values[name] = getattr(spec, name)
        return cls(**values)

    def sign(self, kind: SignKind | str) -> Sign:
        """The sign added for ``kind``."""
        return getattr(self, _kind(kind).value)

    def probability(self, kind: SignKind | str) -> float | None:
        """The probability added with ``kind`` (``None`` for clues: every intersection)."""
        kind = _kind(kind)
        return None if kind is SignKind.CLUE else getattr(self, f"p_{kind.value}")


# -- helpers -------------------------------------------------------------------

Changes = dict[str, object]


def _kind(kind: SignKind | str) -> SignKind:
    try:
        return SignKind(kind)
    except ValueError:
        raise GenomeError(f"unknown sign kind {kind!r} (expected clue, lure or trap)") from None


def _random_kind(kind: SignKind | str) -> SignKind:
    """A kind that has a probability: lure or trap."""
    kind = _kind(kind)
    if kind is SignKind.CLUE:
        raise GenomeError("clues have no probability (every intersection gets one)")
    return kind


def as_spec(maze: MazeLike) -> MazeSpec:
    """``maze`` (a spec, a maze or a maze string) as a spec; :class:`GenomeError` otherwise."""
    if isinstance(maze, MazeSpec):
        return maze
    if isinstance(maze, Maze):
        return maze.spec
    if isinstance(maze, str):
        return MazeSpec.from_string(maze)
    raise GenomeError(f"expected a MazeSpec, a Maze or a maze string, not {maze!r}")


def _acts(spec: MazeSpec, kind: SignKind) -> bool:
    """Whether signs of ``kind`` can be placed: clues and traps need intersections."""
    return kind is SignKind.LURE or not spec.unicursive


def _shifted(value: float, step: float, direction: int, digits: int) -> float:
    """``value + direction * step``, exact, rounded half up to ``digits`` decimals.

    The rounding of :mod:`amaze.curriculum.interpolation`: rational arithmetic
    on the floats' exact values, then half up, so the result is monotone.
    """
    exact = Fraction(value) + direction * Fraction(step)
    scale = 10**digits
    return float(Fraction(math.floor(exact * scale + Fraction(1, 2)), scale))


def draw_change(spec: MazeSpec, rng: np.random.Generator, options: list[Changes]) -> MazeSpec:
    """The spec with one of ``options`` applied (drawn when there are several), or itself."""
    if not options:
        return spec
    changes = options[int(rng.integers(len(options)))] if len(options) > 1 else options[0]
    return spec.where(**changes)


def check_rng(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise GenomeError(f"rng must be a numpy.random.Generator, not {rng!r}")
    return rng


def check_sizes(min_size: object, max_size: object) -> tuple[int, int]:
    low = check_integer("min_size", min_size, minimum=MIN_SIZE, maximum=MAX_SIZE, error=GenomeError)
    high = check_integer("max_size", max_size, minimum=low, maximum=MAX_SIZE, error=GenomeError)
    return low, high


def check_step(name: str, step: object, digits: int) -> float:
    # A step below the rounding grain could round back to the value itself.
    return check_number(name, step, minimum=10**-digits, maximum=1, error=GenomeError)


# -- options of each operator (deterministic: what the operator may change) -----


def size_options(
    spec: MazeSpec, direction: int, step: int, min_size: int, max_size: int, square: bool
) -> list[Changes]:
    def moved(side: int) -> int:
        if direction > 0:
            return min(side + step, max_size) if side < max_size else side
        return max(side - step, min_size) if side > min_size else side

    width, height = moved(spec.width), moved(spec.height)
    grows_w, grows_h = width != spec.width, height != spec.height
    if square:
        return [{"width": width, "height": height}] if grows_w or grows_h else []
    options: list[Changes] = []
    if grows_w:
        options.append({"width": width})
    if grows_h:
        options.append({"height": height})
    if grows_w and grows_h:
        options.append({"width": width, "height": height})
    return options


def start_options(spec: MazeSpec) -> list[Changes]:
    return [{"start": start} for start in StartLocation if start != spec.start]


def add_options(spec: MazeSpec, kind: SignKind, signs: SignSet) -> list[Changes]:
    if getattr(spec, kind.value) or not _acts(spec, kind):
        return []
    changes: Changes = {kind.value: (signs.sign(kind),)}
    if kind is not SignKind.CLUE:
        changes[f"p_{kind.value}"] = signs.probability(kind)
    return [changes]


def remove_options(spec: MazeSpec, kind: SignKind) -> list[Changes]:
    if not getattr(spec, kind.value) or not _acts(spec, kind):
        return []
    changes: Changes = {kind.value: ()}
    if kind is not SignKind.CLUE:
        changes[f"p_{kind.value}"] = None
    return [changes]


def probability_options(
    spec: MazeSpec, kind: SignKind, direction: int, step: float
) -> list[Changes]:
    name = f"p_{kind.value}"
    value = getattr(spec, name)
    if value is None or not _acts(spec, kind):
        return []
    new = min(_shifted(value, step, direction, PROBABILITY_DIGITS), 1.0)
    moves = new > value if direction > 0 else 0 < new < value
    return [{name: new}] if moves else []


def lightness_options(spec: MazeSpec, kind: SignKind, direction: int, step: float) -> list[Changes]:
    signs: tuple[Sign, ...] = getattr(spec, kind.value)
    if not _acts(spec, kind):
        return []
    options: list[Changes] = []
    for k, sign in enumerate(signs):
        new = min(_shifted(sign.value, step, direction, LIGHTNESS_DIGITS), 1.0)
        if (new > sign.value) if direction > 0 else (0 < new < sign.value):
            options.append({kind.value: (*signs[:k], Sign(sign.shape, new), *signs[k + 1 :])})
    return options


# -- the operators ---------------------------------------------------------------


def new_seed(spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
    """The same maze description with another seed: new walls, same family.

    The seed is drawn uniformly in ``[0, 2**31)`` among the seeds other than the
    current one, so the mutant always differs. Always applicable.
    """
    spec = as_spec(spec)
    rng = check_rng(rng)
    if spec.seed < SEED_RANGE:
        seed = int(rng.integers(SEED_RANGE - 1))
        if seed >= spec.seed:  # skip the current seed
            seed += 1
    else:
        seed = int(rng.integers(SEED_RANGE))
    return spec.where(seed=seed)


def size_up(
    spec: MazeLike,
    rng: np.random.Generator,
    *,
    step: int = 1,
    min_size: int = DEFAULT_MIN_SIZE,
    max_size: int = MAX_SIZE,
    square: bool = False,
) -> MazeSpec:
    """A larger maze: a longer path with more intersections, so more decisions.

    The width, the height or both (drawn among those below ``max_size``) grow
    by ``step`` cells, stopping at ``max_size``; with ``square`` both grow
    together, so a square maze stays square. At the bound (every side at
    ``max_size`` or beyond) the spec is returned unchanged.
    """
    spec = as_spec(spec)
    check_rng(rng)
    step = check_integer("size step", step, minimum=1, maximum=MAX_SIZE, error=GenomeError)
    low, high = check_sizes(min_size, max_size)
    return draw_change(spec, rng, size_options(spec, +1, step, low, high, bool(square)))


def size_down(
    spec: MazeLike,
    rng: np.random.Generator,
    *,
    step: int = 1,
    min_size: int = DEFAULT_MIN_SIZE,
    max_size: int = MAX_SIZE,
    square: bool = False,
) -> MazeSpec:
    """A smaller maze: the mirror of :func:`size_up`, stopping at ``min_size``.

    A side outside ``[min_size, max_size]`` only ever moves towards the bounds.
    """
    spec = as_spec(spec)
    check_rng(rng)
    step = check_integer("size step", step, minimum=1, maximum=MAX_SIZE, error=GenomeError)
    low, high = check_sizes(min_size, max_size)
    return draw_change(spec, rng, size_options(spec, -1, step, low, high, bool(square)))


def new_start(spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
    """The maze started from another corner, drawn among the three others.

    For a rotated maze (the default) this is the same maze turned: the same
    difficulty seen through other inputs, which tests whether an agent's
    skills hold in every orientation. Always applicable.
    """
    spec = as_spec(spec)
    return draw_change(spec, check_rng(rng), start_options(spec))


def toggle_unicursive(spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
    """Intersections off (a unicursive maze: one corridor) or back on.

    Turning them off silences clues and traps (they are placed at
    intersections) without removing them from the spec; turning them on
    brings back the decisions, and the clues and traps with them. Draws
    nothing; always applicable.
    """
    spec = as_spec(spec)
    check_rng(rng)
    return spec.where(unicursive=not spec.unicursive)


def add_signs(
    spec: MazeLike,
    rng: np.random.Generator,
    kind: SignKind | str,
    *,
    signs: SignSet | None = None,
) -> MazeSpec:
    """The maze with a sign kind it lacks: clues (help), lures or traps (deception).

    The kind gets ``signs``'s sign of that kind and, for lures and traps, its
    probability (default: the paper's, :class:`SignSet`). Not applicable (the
    spec returned unchanged) when the maze already has that kind, or for clues
    and traps in a unicursive maze. Draws nothing.
    """
    spec = as_spec(spec)
    check_rng(rng)
    if signs is None:
        signs = SignSet()
    if not isinstance(signs, SignSet):
        raise GenomeError(f"signs must be a SignSet, not {signs!r}")
    return draw_change(spec, rng, add_options(spec, _kind(kind), signs))


def remove_signs(spec: MazeLike, rng: np.random.Generator, kind: SignKind | str) -> MazeSpec:
    """The maze without a sign kind (and its probability).

    Not applicable when the maze has no such sign, or for clues and traps in a
    unicursive maze (they are dormant there). Draws nothing.
    """
    spec = as_spec(spec)
    check_rng(rng)
    return draw_change(spec, rng, remove_options(spec, _kind(kind)))


def probability_up(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """More lures (of the corridor cells) or traps (of the intersections): more deception.

    The probability grows by ``step`` (rounded half up to 3 decimals, at most 1).
    Not applicable at 1, without signs of that kind, or for traps in a
    unicursive maze. Draws nothing.
    """
    spec = as_spec(spec)
    check_rng(rng)
    step = check_step("probability step", step, PROBABILITY_DIGITS)
    return draw_change(spec, rng, probability_options(spec, _random_kind(kind), +1, step))


def probability_down(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """Fewer lures or traps: the probability shrinks by ``step``.

    Never down to 0 (that would remove the kind: :func:`remove_signs` does it):
    not applicable when the step would reach 0, and as :func:`probability_up`
    otherwise. Draws nothing.
    """
    spec = as_spec(spec)
    check_rng(rng)
    step = check_step("probability step", step, PROBABILITY_DIGITS)
    return draw_change(spec, rng, probability_options(spec, _random_kind(kind), -1, step))


def lightness_up(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """One sign of ``kind`` made lighter by ``step`` (rounded to 3 decimals, at most 1).

    Lightness is what a discrete agent perceives of a sign: moving a lure's or
    a trap's lightness towards the clues' makes them harder to tell apart
    (the inseparability of the sign set). The sign is drawn among the kind's
    signs that can move. Not applicable when none can, or for clues and traps
    in a unicursive maze.
    """
    spec = as_spec(spec)
    check_rng(rng)
    step = check_step("lightness step", step, LIGHTNESS_DIGITS)
    return draw_change(spec, rng, lightness_options(spec, _kind(kind), +1, step))


def lightness_down(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """One sign of ``kind`` made darker by ``step``; never down to 0 (no sign is invisible).

    Otherwise as :func:`lightness_up`.
    """
    spec = as_spec(spec)
    check_rng(rng)
    step = check_step("lightness step", step, LIGHTNESS_DIGITS)
    return draw_change(spec, rng, lightness_options(spec, _kind(kind), -1, step))


def _kind_fields(kind: SignKind) -> frozenset[str]:
    if kind is SignKind.CLUE:
        return frozenset({"clue"})
    return frozenset({kind.value, f"p_{kind.value}"})


#: Every operator's name and the spec fields it may change, in the order of
#: :meth:`MazeGenome.operators`.
OPERATOR_FIELDS: Mapping[str, frozenset[str]] = MappingProxyType(
    {
        "seed": frozenset({"seed"}),
        "size_up": frozenset({"width", "height"}),
        "size_down": frozenset({"width", "height"}),
        "start": frozenset({"start"}),
        "unicursive": frozenset({"unicursive"}),
        **{f"add_{k.value}": _kind_fields(k) for k in SignKind},
        **{f"remove_{k.value}": _kind_fields(k) for k in SignKind},
        **{
            f"p_{k.value}_{way}": frozenset({f"p_{k.value}"})
            for k in (SignKind.LURE, SignKind.TRAP)
            for way in ("up", "down")
        },
        **{
            f"{k.value}_lightness_{way}": frozenset({k.value})
            for k in SignKind
            for way in ("up", "down")
        },
    }
)

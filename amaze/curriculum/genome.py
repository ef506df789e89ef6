"""The maze genome of the curricula: mutations, a difficulty order and a distance.

Curators (scripted human strategies, an automated co-evolving curator) build
curricula by changing mazes rather than drawing them afresh. Their genome is
the maze string, that is a :class:`~amaze.maze.spec.MazeSpec`; this module
gives them three tools:

* **mutation operators**, one per field of the string (:data:`OPERATOR_FIELDS`),
  gathered with their bounds in :class:`MazeGenome`;
* **a difficulty order**: :class:`DifficultyProfile` (path length,
  intersections, lures, traps, Surprisingness, Deceptiveness), its score
  :func:`difficulty` and the partial order :func:`harder_or_equal`;
* **a distance** between mazes, :func:`maze_distance`, for novelty.

Mutation operators
------------------

Every operator takes a spec and a :class:`numpy.random.Generator` (the only
source of randomness: the same spec and the same generator state give the
same mutant) and returns a new spec that differs from its input only in the
field(s) the operator owns:

===========================  ======================  ================================
operator                     fields                  change
===========================  ======================  ================================
``seed``                     seed                    a fresh seed in ``[0, 2**31)``,
                                                     never the same one (new walls)
``size_up``, ``size_down``   width, height           width, height or both by
                                                     ``size_step`` cells, within
                                                     ``[min_size, max_size]``
``start``                    start                   one of the three other corners
``unicursive``               unicursive              intersections off / on
``add_<kind>``               the kind's signs (and   the :class:`SignSet`'s sign of
                             probability)            that kind, with its probability
``remove_<kind>``            the same                no sign of that kind
``p_<kind>_up``, ``_down``   p_lure or p_trap        the probability by
                                                     ``probability_step``, in (0, 1]
``<kind>_lightness_up``,     the kind's signs        one sign's lightness by
``_down``                                            ``lightness_step``, in (0, 1]
===========================  ======================  ================================

``<kind>`` is ``clue``, ``lure`` or ``trap`` (probabilities: lures and traps).

**Not applicable means unchanged.** Where an operator cannot change the maze
(a size at its bound, a kind already there or absent, a probability at 1...)
it returns its input spec itself, unchanged; :meth:`MazeGenome.applicable`
lists the operators that do change a spec and :meth:`MazeGenome.mutate` draws
only among those. Operators draw from the generator only to choose between
several possible changes (which axis grows, which corner, which sign, the new
seed).

**The grammar's couplings are respected.** A lure (trap) probability exists
exactly when lure (trap) signs do (``MazeSpec`` drops one without the other),
so adding a kind sets both, removing clears both, and a probability step
never reaches 0 (removing the kind is ``remove_<kind>``'s job). Clues and
traps are placed at intersections, which unicursive mazes do not have: in a
unicursive maze the clue and trap operators do not apply (the mutant would be
the same maze). Their signs stay in the spec, dormant, and act again once the
``unicursive`` operator turns intersections back on. Lures sit in corridors
and apply to every maze. The rotation flag (``R``) is inherited, never
mutated. Probabilities and lightness values are rounded half up to
:data:`~amaze.curriculum.interpolation.PROBABILITY_DIGITS` and
:data:`~amaze.curriculum.interpolation.LIGHTNESS_DIGITS` decimals, as the
interpolation curriculum rounds them, so mutants print as short strings.

Every mutant is a valid maze: it generates, its canonical string reads back
to the same spec, and parsing that string emits no ``MazeStringWarning``.
Mutants may fall outside the paper's classes: a maze with intersections and
no clue (after ``remove_clue``, or ``unicursive`` off in a maze without clues)
is of the reference's class ``invalid`` (``Maze.maze_class``), a maze an
agent can still solve, without help at its decisions; curators that want
only the paper's classes filter on it.

Difficulty and distance
-----------------------

:func:`harder_or_equal` is the partial order "at least as hard on every
component" of :class:`DifficultyProfile`; :func:`difficulty`, a positive
weighted sum of the components (:data:`DIFFICULTY_WEIGHTS`), extends it to a
total order that curators sort by. :func:`maze_distance` is a metric on maze
specs, a sum of per-field terms in [0, 1] (a small constant,
:data:`SEED_DISTANCE`, when only the seeds differ).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from fractions import Fraction
from functools import lru_cache
from types import MappingProxyType
from typing import Any

import numpy as np

from amaze.curriculum.interpolation import LIGHTNESS_DIGITS, PROBABILITY_DIGITS
from amaze.errors import AmazeError
from amaze.maze.maze import Maze
from amaze.maze.metrics import compute_metrics
from amaze.maze.signs import Sign, SignKind, as_sign
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec, StartLocation
from amaze.validation import check_integer, check_number

__all__ = [
    "DEFAULT_MIN_SIZE",
    "DIFFICULTY_WEIGHTS",
    "OPERATOR_FIELDS",
    "SEED_DISTANCE",
    "SEED_RANGE",
    "DifficultyProfile",
    "GenomeError",
    "MazeGenome",
    "SignSet",
    "add_signs",
    "difficulty",
    "difficulty_profile",
    "distance_components",
    "harder_or_equal",
    "lightness_down",
    "lightness_up",
    "maze_distance",
    "new_seed",
    "new_start",
    "probability_down",
    "probability_up",
    "remove_signs",
    "size_down",
    "size_up",
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
        spec = _as_spec(maze)
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

_Changes = dict[str, object]


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


def _as_spec(maze: MazeLike) -> MazeSpec:
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


def _draw(spec: MazeSpec, rng: np.random.Generator, options: list[_Changes]) -> MazeSpec:
    """The spec with one of ``options`` applied (drawn when there are several), or itself."""
    if not options:
        return spec
    changes = options[int(rng.integers(len(options)))] if len(options) > 1 else options[0]
    return spec.where(**changes)


def _check_rng(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise GenomeError(f"rng must be a numpy.random.Generator, not {rng!r}")
    return rng


def _check_sizes(min_size: object, max_size: object) -> tuple[int, int]:
    low = check_integer("min_size", min_size, minimum=MIN_SIZE, maximum=MAX_SIZE, error=GenomeError)
    high = check_integer("max_size", max_size, minimum=low, maximum=MAX_SIZE, error=GenomeError)
    return low, high


def _check_step(name: str, step: object, digits: int) -> float:
    # A step below the rounding grain could round back to the value itself.
    return check_number(name, step, minimum=10**-digits, maximum=1, error=GenomeError)


# -- options of each operator (deterministic: what the operator may change) -----


def _size_options(
    spec: MazeSpec, direction: int, step: int, min_size: int, max_size: int, square: bool
) -> list[_Changes]:
    def moved(side: int) -> int:
        if direction > 0:
            return min(side + step, max_size) if side < max_size else side
        return max(side - step, min_size) if side > min_size else side

    width, height = moved(spec.width), moved(spec.height)
    grows_w, grows_h = width != spec.width, height != spec.height
    if square:
        return [{"width": width, "height": height}] if grows_w or grows_h else []
    options: list[_Changes] = []
    if grows_w:
        options.append({"width": width})
    if grows_h:
        options.append({"height": height})
    if grows_w and grows_h:
        options.append({"width": width, "height": height})
    return options


def _start_options(spec: MazeSpec) -> list[_Changes]:
    return [{"start": start} for start in StartLocation if start != spec.start]


def _add_options(spec: MazeSpec, kind: SignKind, signs: SignSet) -> list[_Changes]:
    if getattr(spec, kind.value) or not _acts(spec, kind):
        return []
    changes: _Changes = {kind.value: (signs.sign(kind),)}
    if kind is not SignKind.CLUE:
        changes[f"p_{kind.value}"] = signs.probability(kind)
    return [changes]


def _remove_options(spec: MazeSpec, kind: SignKind) -> list[_Changes]:
    if not getattr(spec, kind.value) or not _acts(spec, kind):
        return []
    changes: _Changes = {kind.value: ()}
    if kind is not SignKind.CLUE:
        changes[f"p_{kind.value}"] = None
    return [changes]


def _probability_options(
    spec: MazeSpec, kind: SignKind, direction: int, step: float
) -> list[_Changes]:
    name = f"p_{kind.value}"
    value = getattr(spec, name)
    if value is None or not _acts(spec, kind):
        return []
    new = min(_shifted(value, step, direction, PROBABILITY_DIGITS), 1.0)
    moves = new > value if direction > 0 else 0 < new < value
    return [{name: new}] if moves else []


def _lightness_options(
    spec: MazeSpec, kind: SignKind, direction: int, step: float
) -> list[_Changes]:
    signs: tuple[Sign, ...] = getattr(spec, kind.value)
    if not _acts(spec, kind):
        return []
    options: list[_Changes] = []
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
    spec = _as_spec(spec)
    rng = _check_rng(rng)
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
    spec = _as_spec(spec)
    _check_rng(rng)
    step = check_integer("size step", step, minimum=1, maximum=MAX_SIZE, error=GenomeError)
    low, high = _check_sizes(min_size, max_size)
    return _draw(spec, rng, _size_options(spec, +1, step, low, high, bool(square)))


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
    spec = _as_spec(spec)
    _check_rng(rng)
    step = check_integer("size step", step, minimum=1, maximum=MAX_SIZE, error=GenomeError)
    low, high = _check_sizes(min_size, max_size)
    return _draw(spec, rng, _size_options(spec, -1, step, low, high, bool(square)))


def new_start(spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
    """The maze started from another corner, drawn among the three others.

    For a rotated maze (the default) this is the same maze turned: the same
    difficulty seen through other inputs, which tests whether an agent's
    skills hold in every orientation. Always applicable.
    """
    spec = _as_spec(spec)
    return _draw(spec, _check_rng(rng), _start_options(spec))


def toggle_unicursive(spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
    """Intersections off (a unicursive maze: one corridor) or back on.

    Turning them off silences clues and traps (they are placed at
    intersections) without removing them from the spec; turning them on
    brings back the decisions, and the clues and traps with them. Draws
    nothing; always applicable.
    """
    spec = _as_spec(spec)
    _check_rng(rng)
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
    spec = _as_spec(spec)
    _check_rng(rng)
    if signs is None:
        signs = SignSet()
    if not isinstance(signs, SignSet):
        raise GenomeError(f"signs must be a SignSet, not {signs!r}")
    return _draw(spec, rng, _add_options(spec, _kind(kind), signs))


def remove_signs(spec: MazeLike, rng: np.random.Generator, kind: SignKind | str) -> MazeSpec:
    """The maze without a sign kind (and its probability).

    Not applicable when the maze has no such sign, or for clues and traps in a
    unicursive maze (they are dormant there). Draws nothing.
    """
    spec = _as_spec(spec)
    _check_rng(rng)
    return _draw(spec, rng, _remove_options(spec, _kind(kind)))


def probability_up(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """More lures (of the corridor cells) or traps (of the intersections): more deception.

    The probability grows by ``step`` (rounded half up to 3 decimals, at most 1).
    Not applicable at 1, without signs of that kind, or for traps in a
    unicursive maze. Draws nothing.
    """
    spec = _as_spec(spec)
    _check_rng(rng)
    step = _check_step("probability step", step, PROBABILITY_DIGITS)
    return _draw(spec, rng, _probability_options(spec, _random_kind(kind), +1, step))


def probability_down(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """Fewer lures or traps: the probability shrinks by ``step``.

    Never down to 0 (that would remove the kind: :func:`remove_signs` does it):
    not applicable when the step would reach 0, and as :func:`probability_up`
    otherwise. Draws nothing.
    """
    spec = _as_spec(spec)
    _check_rng(rng)
    step = _check_step("probability step", step, PROBABILITY_DIGITS)
    return _draw(spec, rng, _probability_options(spec, _random_kind(kind), -1, step))


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
    spec = _as_spec(spec)
    _check_rng(rng)
    step = _check_step("lightness step", step, LIGHTNESS_DIGITS)
    return _draw(spec, rng, _lightness_options(spec, _kind(kind), +1, step))


def lightness_down(
    spec: MazeLike, rng: np.random.Generator, kind: SignKind | str, *, step: float = 0.05
) -> MazeSpec:
    """One sign of ``kind`` made darker by ``step``; never down to 0 (no sign is invisible).

    Otherwise as :func:`lightness_up`.
    """
    spec = _as_spec(spec)
    _check_rng(rng)
    step = _check_step("lightness step", step, LIGHTNESS_DIGITS)
    return _draw(spec, rng, _lightness_options(spec, _kind(kind), -1, step))


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


# -- the genome ----------------------------------------------------------------


@dataclass(frozen=True)
class MazeGenome:
    """The mutation operators of maze strings, with their bounds.

    ``min_size``/``max_size`` bound the sides that ``size_up``/``size_down``
    produce (``size_step`` cells at a time; ``square`` moves both sides
    together); ``probability_step`` and ``lightness_step`` are the steps of the
    lure/trap probabilities and of sign lightness; ``signs`` the signs that
    ``add_<kind>`` puts in. A curator keeps one genome and calls
    :meth:`mutate` with its own generator.
    """

    min_size: int = DEFAULT_MIN_SIZE
    max_size: int = MAX_SIZE
    size_step: int = 1
    square: bool = False
    probability_step: float = 0.05
    lightness_step: float = 0.05
    signs: SignSet = field(default_factory=SignSet)

    def __post_init__(self) -> None:
        low, high = _check_sizes(self.min_size, self.max_size)
        set_ = object.__setattr__
        set_(self, "min_size", low)
        set_(self, "max_size", high)
        step = check_integer(
            "size_step", self.size_step, minimum=1, maximum=MAX_SIZE, error=GenomeError
        )
        set_(self, "size_step", step)
        if not isinstance(self.square, bool):
            raise GenomeError(f"square {self.square!r} is not a bool")
        set_(
            self,
            "probability_step",
            _check_step("probability_step", self.probability_step, PROBABILITY_DIGITS),
        )
        set_(
            self,
            "lightness_step",
            _check_step("lightness_step", self.lightness_step, LIGHTNESS_DIGITS),
        )
        if not isinstance(self.signs, SignSet):
            raise GenomeError(f"signs must be a SignSet, not {self.signs!r}")

    def operators(self) -> tuple[str, ...]:
        """The names of every operator (see :data:`OPERATOR_FIELDS` for what each changes)."""
        return tuple(OPERATOR_FIELDS)

    def applicable(self, spec: MazeLike, operators: Iterable[str] | None = None) -> tuple[str, ...]:
        """The operators (of ``operators``, default all) that change ``spec``."""
        spec = _as_spec(spec)
        return tuple(
            name for name in self._names(operators) if name == "seed" or _OPTIONS[name](self, spec)
        )

    def apply(self, name: str, spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
        """The mutant of ``spec`` by the operator ``name`` (``spec`` itself if not applicable)."""
        (name,) = self._names([name])
        spec = _as_spec(spec)
        rng = _check_rng(rng)
        if name == "seed":
            return new_seed(spec, rng)
        return _draw(spec, rng, _OPTIONS[name](self, spec))

    def mutate(
        self,
        spec: MazeLike,
        rng: np.random.Generator,
        operators: Iterable[str] | None = None,
        n: int = 1,
    ) -> MazeSpec:
        """``n`` successive mutations, each by an operator drawn uniformly among the applicable.

        ``operators`` restricts the choice to some names (default: all); a name
        listed k times is drawn k times as often, which weights the operators.
        When no operator of the choice applies, the current spec is returned as
        it is.
        Successive mutations may undo each other (``unicursive`` twice).
        """
        names = self._names(operators)
        n = check_integer("n", n, minimum=0, error=GenomeError)
        current = _as_spec(spec)
        rng = _check_rng(rng)
        for _ in range(n):
            candidates = self.applicable(current, names)
            if not candidates:
                break
            name = candidates[int(rng.integers(len(candidates)))]
            current = self.apply(name, current, rng)
        return current

    def _names(self, operators: Iterable[str] | None) -> tuple[str, ...]:
        if operators is None:
            return self.operators()
        if isinstance(operators, str):
            operators = (operators,)
        names = tuple(operators)
        unknown = [name for name in names if name not in OPERATOR_FIELDS]
        if unknown:
            raise GenomeError(
                f"unknown mutation operator(s) {', '.join(map(repr, unknown))}"
                f" (known: {', '.join(OPERATOR_FIELDS)})"
            )
        return names


_Options = Callable[[MazeGenome, MazeSpec], list[_Changes]]


def _options_table() -> dict[str, _Options]:
    """What each operator but ``seed`` may change in a spec, under a genome's bounds."""

    def sizes(genome: MazeGenome) -> tuple[int, int, int, bool]:
        return genome.size_step, genome.min_size, genome.max_size, genome.square

    table: dict[str, _Options] = {
        "size_up": lambda g, s: _size_options(s, +1, *sizes(g)),
        "size_down": lambda g, s: _size_options(s, -1, *sizes(g)),
        "start": lambda g, s: _start_options(s),
        "unicursive": lambda g, s: [{"unicursive": not s.unicursive}],
    }
    for k in SignKind:
        table[f"add_{k.value}"] = lambda g, s, k=k: _add_options(s, k, g.signs)
        table[f"remove_{k.value}"] = lambda g, s, k=k: _remove_options(s, k)
    for way, d in (("up", +1), ("down", -1)):
        for k in (SignKind.LURE, SignKind.TRAP):
            table[f"p_{k.value}_{way}"] = lambda g, s, k=k, d=d: _probability_options(
                s, k, d, g.probability_step
            )
        for k in SignKind:
            table[f"{k.value}_lightness_{way}"] = lambda g, s, k=k, d=d: _lightness_options(
                s, k, d, g.lightness_step
            )
    return table


_OPTIONS = _options_table()


# -- difficulty -------------------------------------------------------------------

#: The weight of each component of :class:`DifficultyProfile` in its score
#: (per cell, per intersection, per lure, per trap, per bit, per bit).
DIFFICULTY_WEIGHTS: Mapping[str, float] = MappingProxyType(
    {
        "path_length": 0.01,
        "intersections": 0.1,
        "lures": 0.02,
        "traps": 0.5,
        "surprisingness": 1.0,
        "deceptiveness": 0.25,
    }
)


@dataclass(frozen=True)
class DifficultyProfile:
    """What makes a maze hard, component by component (each: the larger, the harder).

    * ``path_length``: the cells of the solution (the paper's ``l``): the
      length of the task, the number of moves an agent must get right;
    * ``intersections``: the decisions on the path, where a wrong move leads
      into a dead end;
    * ``lures``: signs in corridors pointing a wrong way; the walls still show
      the way, so a lure misleads only an agent that trusts signs blindly;
    * ``traps``: signs at intersections pointing a wrong, open way. The paper
      finds them the hard part: the agent must go against a sign that looks
      like a clue. They are counted on their own because the metrics can miss
      them (a single trap replacing a clue changes neither the input entropy
      nor the deceptiveness of ``M4_10x10_C1``);
    * ``surprisingness``: the paper's S(M), the entropy (bits) of the inputs
      along the solution: how unpredictable the situations an agent meets are;
    * ``deceptiveness``: the paper's D(M) (the rotation-invariant variant,
      :func:`~amaze.maze.metrics.invariant_deceptiveness`), the entropy (bits)
      of the misleading signs (lures and traps) among inputs with the same
      walls: how hard they are to recognise.

    Every component is the same for the four rotations of a rotated maze.
    """

    path_length: int
    intersections: int
    lures: int
    traps: int
    surprisingness: float
    deceptiveness: float

    @classmethod
    def of(cls, maze: MazeLike) -> DifficultyProfile:
        """The profile of a maze (a spec or a string is generated first)."""
        if not isinstance(maze, Maze):
            maze = Maze.generate(_as_spec(maze))
        metrics = compute_metrics(maze)
        return cls(
            path_length=maze.path_length,
            intersections=maze.n_intersections,
            lures=len(maze.lures),
            traps=len(maze.traps),
            surprisingness=metrics.surprisingness,
            deceptiveness=metrics.invariant_deceptiveness,
        )

    def components(self) -> dict[str, float]:
        """``{component: value}``, in the order of :data:`DIFFICULTY_WEIGHTS`."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def score(self, weights: Mapping[str, float] = DIFFICULTY_WEIGHTS) -> float:
        """``sum(weights[c] * value(c))``: one number that curators sort mazes by.

        With the default weights the paper's 20x20 training maze scores about
        10.2: its path (101 cells) counts about 1, its 6 intersections 0.6,
        24 lures 0.5, 3 traps 1.5, S 4.6 and D 2.0. The weights are
        positive, so the score never contradicts :meth:`dominates`.
        """
        missing = set(DIFFICULTY_WEIGHTS) - set(weights)
        if missing:
            raise GenomeError(f"difficulty weights lack {', '.join(sorted(missing))}")
        return math.fsum(weights[name] * value for name, value in self.components().items())

    def dominates(self, other: DifficultyProfile) -> bool:
        """At least as hard as ``other`` on every component (the partial order)."""
        mine, theirs = self.components(), other.components()
        return all(mine[name] >= theirs[name] for name in mine)


def _profile(maze: MazeLike | DifficultyProfile) -> DifficultyProfile:
    return maze if isinstance(maze, DifficultyProfile) else DifficultyProfile.of(maze)


def difficulty_profile(maze: MazeLike) -> DifficultyProfile:
    """The :class:`DifficultyProfile` of a maze, a spec or a maze string."""
    return DifficultyProfile.of(maze)


def difficulty(maze: MazeLike | DifficultyProfile) -> float:
    """The difficulty score of a maze (:meth:`DifficultyProfile.score`, default weights).

    ``sorted(mazes, key=difficulty)`` orders mazes from easy to hard; the score
    is a linear extension of :func:`harder_or_equal`.
    """
    return _profile(maze).score()


def harder_or_equal(a: MazeLike | DifficultyProfile, b: MazeLike | DifficultyProfile) -> bool:
    """The partial order of difficulty: ``a`` is at least as hard as ``b`` on every component.

    Path length, intersections, lures, traps, Surprisingness and Deceptiveness
    of ``a`` are all >= those of ``b``. Reflexive, antisymmetric on profiles
    and transitive; two mazes may be incomparable (a long unicursive maze and a
    short one with traps), which is when a curator needs :func:`difficulty`.
    Profiles may be given instead of mazes, to avoid generating twice.
    """
    return _profile(a).dominates(_profile(b))


# -- distance -----------------------------------------------------------------

#: The distance between two mazes that differ only in their seed.
SEED_DISTANCE = 0.1
#: What two signs at the same position differ by when their shapes differ.
SHAPE_DISTANCE = 0.5
#: What a sign differs by from no sign (a sign list shorter than the other).
MISSING_SIGN_DISTANCE = 1.0

_LOG_SIZE_RANGE = math.log(MAX_SIZE / MIN_SIZE)


def _signs_distance(a: tuple[Sign, ...], b: tuple[Sign, ...]) -> float:
    total = 0.0
    for k in range(max(len(a), len(b))):
        if k >= len(a) or k >= len(b):
            total += MISSING_SIGN_DISTANCE
        else:
            total += abs(a[k].value - b[k].value) + SHAPE_DISTANCE * (a[k].shape != b[k].shape)
    return min(total, 1.0)


def _log_gap(a: int, b: int) -> float:
    return abs(math.log(a) - math.log(b))


def _corner_bits(start: StartLocation) -> tuple[bool, bool]:
    east = start in (StartLocation.SOUTH_EAST, StartLocation.NORTH_EAST)
    north = start in (StartLocation.NORTH_EAST, StartLocation.NORTH_WEST)
    return east, north


@lru_cache(maxsize=4096)
def _metric_point(spec: MazeSpec) -> tuple[float, float]:
    metrics = compute_metrics(Maze.generate(spec))
    return metrics.surprisingness, metrics.invariant_deceptiveness


def distance_components(
    a: MazeLike, b: MazeLike, *, metrics_weight: float = 0.0
) -> dict[str, float]:
    """The terms of :func:`maze_distance`, by name (each a metric or pseudometric, >= 0)."""
    weight = check_number("metrics_weight", metrics_weight, minimum=0, error=GenomeError)
    x, y = _as_spec(a), _as_spec(b)
    (xe, xn), (ye, yn) = _corner_bits(x.start), _corner_bits(y.start)
    terms = {
        # differences of logarithms (not the logarithm of a ratio): exactly symmetric
        "size": (_log_gap(x.width, y.width) + _log_gap(x.height, y.height)) / (2 * _LOG_SIZE_RANGE),
        "start": ((xe != ye) + (xn != yn)) / 2,
        "rotated": float(x.rotated != y.rotated),
        "unicursive": float(x.unicursive != y.unicursive),
        **{k.value: _signs_distance(getattr(x, k.value), getattr(y, k.value)) for k in SignKind},
        "p_lure": abs((x.p_lure or 0.0) - (y.p_lure or 0.0)),
        "p_trap": abs((x.p_trap or 0.0) - (y.p_trap or 0.0)),
        "seed": SEED_DISTANCE * (x.seed != y.seed),
    }
    if weight:
        (sx, dx), (sy, dy) = _metric_point(x), _metric_point(y)
        terms["metrics"] = weight * (abs(sx - sy) + abs(dx - dy))
    return terms


def maze_distance(a: MazeLike, b: MazeLike, *, metrics_weight: float = 0.0) -> float:
    """A distance between maze strings, field by field, for novelty among curated mazes.

    The sum of per-field terms, each in [0, 1] (so roughly "how many fields
    differ"):

    * ``size``: ``(|ln w_a - ln w_b| + |ln h_a - ln h_b|) / (2 ln(100/2))``;
      relative, as going from 5 to 10 cells changes a maze as much as from
      50 to 100;
    * ``start``: half the number of axes (east-west, south-north) on which the
      corners differ: 1/2 for a neighbouring corner, 1 for the opposite one;
    * ``rotated``, ``unicursive``: 1 when the flags differ;
    * ``clue``, ``lure``, ``trap``: 1 when one maze has that kind and the other
      not; otherwise, sign by sign in the list's order, the difference of
      lightness plus 1/2 when the shapes differ (1 per sign one list has
      beyond the other), capped at 1;
    * ``p_lure``, ``p_trap``: the difference of probabilities (0 without the kind);
    * ``seed``: :data:`SEED_DISTANCE` (0.1) when the seeds differ. Another
      seed gives other walls but the same family of mazes: different, yet
      closer than any change of the description that is not small;
    * with ``metrics_weight > 0``: that weight times the differences of
      Surprisingness and (invariant) Deceptiveness in bits
      (``|S_a - S_b| + |D_a - D_b|``); the mazes are generated for it (once
      per spec, cached).

    Each term is a metric or a pseudometric on specs and together they
    separate specs, so the sum is a metric on maze specifications: symmetric,
    zero exactly for the same spec, and it satisfies the triangle inequality.
    Dormant clues and traps of a unicursive maze count, as they act again when
    intersections are turned on.
    """
    return math.fsum(distance_components(a, b, metrics_weight=metrics_weight).values())

"""The maze genome of the curricula: mutation operators, one per field of the maze string.

Curators (scripted human strategies, an automated co-evolving curator) build
curricula by changing mazes rather than drawing them afresh. Their genome is
the maze string, that is a :class:`~amaze.maze.spec.MazeSpec`; this module
gives them three tools:

* **mutation operators**, one per field of the string (:data:`OPERATOR_FIELDS`),
  gathered with their bounds in :class:`MazeGenome`;
* with them (their own modules), **a difficulty order**
  (:mod:`amaze.curriculum.difficulty`) and **a distance** between mazes for
  novelty (:mod:`amaze.curriculum.distance`).

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

The difficulty order (:mod:`amaze.curriculum.difficulty`) and the distance
(:mod:`amaze.curriculum.distance`) that curators use beside the genome live
in modules of their own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from amaze.curriculum.interpolation import LIGHTNESS_DIGITS, PROBABILITY_DIGITS
from amaze.curriculum.mutations import (
    DEFAULT_MIN_SIZE,
    OPERATOR_FIELDS,
    SEED_RANGE,
    Changes,
    GenomeError,
    SignSet,
    add_options,
    add_signs,
    as_spec,
    check_rng,
    check_sizes,
    check_step,
    draw_change,
    lightness_down,
    lightness_options,
    lightness_up,
    new_seed,
    new_start,
    probability_down,
    probability_options,
    probability_up,
    remove_options,
    remove_signs,
    size_down,
    size_options,
    size_up,
    start_options,
    toggle_unicursive,
)
from amaze.maze.maze import Maze
from amaze.maze.signs import SignKind
from amaze.maze.spec import MAX_SIZE, MazeSpec
from amaze.validation import check_integer

__all__ = [
    "DEFAULT_MIN_SIZE",
    "OPERATOR_FIELDS",
    "SEED_RANGE",
    "GenomeError",
    "MazeGenome",
    "SignSet",
    "add_signs",
    "lightness_down",
    "lightness_up",
    "new_seed",
    "new_start",
    "probability_down",
    "probability_up",
    "remove_signs",
    "size_down",
    "size_up",
    "toggle_unicursive",
]

MazeLike = MazeSpec | Maze | str


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
        low, high = check_sizes(self.min_size, self.max_size)
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
            check_step("probability_step", self.probability_step, PROBABILITY_DIGITS),
        )
        set_(
            self,
            "lightness_step",
            check_step("lightness_step", self.lightness_step, LIGHTNESS_DIGITS),
        )
        if not isinstance(self.signs, SignSet):
            raise GenomeError(f"signs must be a SignSet, not {self.signs!r}")

    def operators(self) -> tuple[str, ...]:
        """The names of every operator (see :data:`OPERATOR_FIELDS` for what each changes)."""
        return tuple(OPERATOR_FIELDS)

    def applicable(self, spec: MazeLike, operators: Iterable[str] | None = None) -> tuple[str, ...]:
        """The operators (of ``operators``, default all) that change ``spec``."""
        spec = as_spec(spec)
        return tuple(
            name for name in self._names(operators) if name == "seed" or _OPTIONS[name](self, spec)
        )

    def apply(self, name: str, spec: MazeLike, rng: np.random.Generator) -> MazeSpec:
        """The mutant of ``spec`` by the operator ``name`` (``spec`` itself if not applicable)."""
        (name,) = self._names([name])
        spec = as_spec(spec)
        rng = check_rng(rng)
        if name == "seed":
            return new_seed(spec, rng)
        return draw_change(spec, rng, _OPTIONS[name](self, spec))

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
        current = as_spec(spec)
        rng = check_rng(rng)
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


_Options = Callable[[MazeGenome, MazeSpec], list[Changes]]


def _options_table() -> dict[str, _Options]:
    """What each operator but ``seed`` may change in a spec, under a genome's bounds."""

    def sizes(genome: MazeGenome) -> tuple[int, int, int, bool]:
        return genome.size_step, genome.min_size, genome.max_size, genome.square

    table: dict[str, _Options] = {
        "size_up": lambda g, s: size_options(s, +1, *sizes(g)),
        "size_down": lambda g, s: size_options(s, -1, *sizes(g)),
        "start": lambda g, s: start_options(s),
        "unicursive": lambda g, s: [{"unicursive": not s.unicursive}],
    }
    for k in SignKind:
        table[f"add_{k.value}"] = lambda g, s, k=k: add_options(s, k, g.signs)
        table[f"remove_{k.value}"] = lambda g, s, k=k: remove_options(s, k)
    for way, d in (("up", +1), ("down", -1)):
        for k in (SignKind.LURE, SignKind.TRAP):
            table[f"p_{k.value}_{way}"] = lambda g, s, k=k, d=d: probability_options(
                s, k, d, g.probability_step
            )
        for k in SignKind:
            table[f"{k.value}_lightness_{way}"] = lambda g, s, k=k, d=d: lightness_options(
                s, k, d, g.lightness_step
            )
    return table


_OPTIONS = _options_table()

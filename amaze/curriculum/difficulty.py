"""How hard a maze is: a difficulty profile, its score and a partial order.

:class:`DifficultyProfile` holds the components of a maze's difficulty
(path length, intersections, lures, traps, Surprisingness, Deceptiveness);
:func:`harder_or_equal` is the partial order "at least as hard on every
component"; :func:`difficulty`, a positive weighted sum of the components
(:data:`DIFFICULTY_WEIGHTS`), extends it to a total order that curators,
the co-evolved maze population and the browser curator sort by.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType

from amaze.curriculum.mutations import GenomeError, as_spec
from amaze.maze.maze import Maze
from amaze.maze.metrics import compute_metrics
from amaze.maze.spec import MazeSpec

__all__ = [
    "DIFFICULTY_WEIGHTS",
    "DifficultyProfile",
    "difficulty",
    "difficulty_profile",
    "harder_or_equal",
]

MazeLike = MazeSpec | Maze | str

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
            maze = Maze.generate(as_spec(maze))
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

    >>> sorted(["M4_10x10_C1_t.5_T.5", "M4_10x10_U", "M4_10x10_C1"], key=difficulty)
    ['M4_10x10_U', 'M4_10x10_C1', 'M4_10x10_C1_t.5_T.5']
    """
    return _profile(maze).score()


def harder_or_equal(a: MazeLike | DifficultyProfile, b: MazeLike | DifficultyProfile) -> bool:
    """The partial order of difficulty: ``a`` is at least as hard as ``b`` on every component.

    Path length, intersections, lures, traps, Surprisingness and Deceptiveness
    of ``a`` are all >= those of ``b``. Reflexive, antisymmetric on profiles
    and transitive; two mazes may be incomparable (a long unicursive maze and a
    short one with traps), which is when a curator needs :func:`difficulty`.
    Profiles may be given instead of mazes, to avoid generating twice.

    >>> harder_or_equal("M4_10x10_C1_t.5_T.5", "M4_10x10_C1")  # the same maze plus traps
    True
    >>> harder_or_equal("M4_10x10_C1", "M4_10x10_C1_t.5_T.5")
    False
    """
    return _profile(a).dominates(_profile(b))

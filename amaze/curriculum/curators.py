"""The curator protocol: who chooses which agent goes on and which mazes it meets next.

In the EDHuCAT loop (paper, Algorithm 1; :mod:`amaze.runs.curriculum`) a
curator makes the two decisions of every stage:

* ``select(candidates) -> candidate``: which of the stage's branches goes on;
* ``generate(k, history) -> k maze strings``: the mazes of the next stage's
  ``k`` branches (each trained in its 4 rotations).

A :class:`Candidate` shows what a human would see of a branch: the mazes it
trained on and its results on them (success, R̄ and steps, per rotation), its
results on the other branches' mazes of the stage, its lineage, the steps it
spent and its trajectory pictures. :class:`History` is the curriculum so
far. Curators are built from a :class:`CuratorContext` (the target maze, the
run's seed, the numbers of stages and branches...) and draw randomness only
from :meth:`CuratorContext.rng`, derived from the run's seed, so a curator
holds no state of its own and a resumed run asks it the same questions with
the same answers.

**Finding curators by name.** :data:`BUILTIN_CURATORS` are the package's
own (the scripted human strategies of :mod:`amaze.curriculum.strategies`,
the automated EDEnS-style curator of :mod:`amaze.curriculum.edens` and the
terminal curator of :mod:`amaze.curriculum.human`); any installed
distribution adds its own under the entry-point group ``amaze.curators``::

    [project.entry-points."amaze.curators"]
    mine = "my_package.curators:MyCurator"

after which ``--curator mine`` works in ``amaze-train`` and ``amaze-evolve``.
A curator class takes the context as its only argument and has a ``name``;
built-in names cannot be taken by a plug-in.

**Validation mazes.** A curator that judges candidates on mazes none of
them trained on gives them as an attribute ``validation`` (maze strings; see
:mod:`amaze.curriculum.validation` for mazes disjoint from the evaluation
suite): the loop plays every candidate on their 4 rotations and shows the
results in :attr:`Candidate.validation`.
"""

from __future__ import annotations

import functools
import importlib
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from amaze.errors import AmazeError
from amaze.maze import rotations
from amaze.validation import check_integer, check_number, closest

__all__ = [
    "BUILTIN_CURATORS",
    "ENTRY_POINT_GROUP",
    "Candidate",
    "Curator",
    "CuratorContext",
    "CuratorError",
    "History",
    "MazeResults",
    "StageRecord",
    "curator_class",
    "curator_names",
    "make_curator",
    "refuse_unknown_options",
]

#: The entry-point group where installed distributions declare their curators.
ENTRY_POINT_GROUP = "amaze.curators"

#: The package's curators by name, as ``"module:Class"`` (imported when asked for).
BUILTIN_CURATORS: dict[str, str] = {
    "careful": "amaze.curriculum.strategies:CarefulCurator",
    "moderate": "amaze.curriculum.strategies:ModerateCurator",
    "risky": "amaze.curriculum.strategies:RiskyCurator",
    "random": "amaze.curriculum.strategies:RandomCurator",
    "interpolation": "amaze.curriculum.strategies:InterpolationCurator",
    "edens": "amaze.curriculum.edens:EdensCurator",
    "human": "amaze.curriculum.human:TerminalCurator",
    "follow": "amaze.curriculum.follow:FollowCurator",
}


class CuratorError(AmazeError):
    """A curator that cannot be found or built, or a decision that breaks the protocol."""


@dataclass(frozen=True)
class MazeResults:
    """One agent on one maze's 4 rotations (NW, NE, SW, SE start corners)."""

    maze: str
    success: tuple[bool, ...]
    normalized_reward: tuple[float, ...]
    steps: tuple[int, ...]

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.success))

    @property
    def normalized_reward_mean(self) -> float:
        """The mean of the paper's R̄ over the rotations."""
        return float(np.mean(self.normalized_reward))

    @property
    def solved(self) -> bool:
        """True when every rotation was reached."""
        return all(self.success)

    def to_dict(self) -> dict[str, Any]:
        return {
            "maze": self.maze,
            "success": list(self.success),
            "normalized_reward": list(self.normalized_reward),
            "steps": list(self.steps),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> MazeResults:
        """Results read back from JSON; any missing, ill-typed or impossible value raises.

        ``ValueError`` (or ``KeyError``/``TypeError``) names the value: success
        flags are booleans, R̄ a finite number of at most 1, steps counts; the
        three lists are as long.
        """
        success = data["success"]
        if not isinstance(success, list) or not all(isinstance(v, bool) for v in success):
            raise ValueError(f"success {success!r} is not a list of true/false")
        values = data["normalized_reward"] if "normalized_reward" in data else data["paper_reward"]
        # ("paper_reward": the name in result.json files written before it had one name)
        rewards = tuple(check_number("normalized_reward", v, maximum=1.0) for v in values)
        steps = tuple(check_integer("steps", v, minimum=0) for v in data["steps"])
        if not len(success) == len(rewards) == len(steps):
            raise ValueError("success, normalized_reward and steps are not as long as each other")
        return cls(
            maze=str(data["maze"]), success=tuple(success), normalized_reward=rewards, steps=steps
        )


def _mean(values: Sequence[float]) -> float:
    return float(np.mean(values)) if len(values) else float("nan")


@dataclass(frozen=True)
class Candidate:
    """A branch of a stage, as a curator sees it before choosing."""

    stage: int
    branch: int
    #: The mazes the branch trained on (canonical strings; each in its 4 rotations).
    mazes: tuple[str, ...]
    #: Its results on its own mazes, then on the other branches' mazes of the stage.
    own: tuple[MazeResults, ...]
    others: tuple[MazeResults, ...]
    #: The branch chosen at every earlier stage, then this one: ``lineage[s]`` at stage ``s``.
    lineage: tuple[int, ...]
    #: Environment steps and seconds the branch spent in its stage.
    env_steps: int
    seconds: float
    #: True if its training stopped early, every training episode optimal.
    converged: bool
    #: Environment steps of its whole lineage, this stage included.
    lineage_steps: int
    #: Pictures of its trajectories (its own mazes), for a human to look at.
    pictures: tuple[Path, ...] = field(default=(), compare=False)
    #: Its results on the curator's validation mazes (empty if the curator has none).
    validation: tuple[MazeResults, ...] = ()

    @property
    def success_rate(self) -> float:
        """Success rate on its own mazes."""
        return _mean([s for r in self.own for s in r.success])

    @property
    def normalized_reward(self) -> float:
        """Mean R̄ on its own mazes."""
        return _mean([v for r in self.own for v in r.normalized_reward])

    @property
    def solved(self) -> bool:
        """True when it reached the goal in every rotation of its own mazes."""
        return all(r.solved for r in self.own)

    @property
    def overall_success_rate(self) -> float:
        """Success rate on every maze of the stage (its own and the others')."""
        return _mean([s for r in self.own + self.others for s in r.success])

    @property
    def overall_normalized_reward(self) -> float:
        """Mean R̄ on every maze of the stage."""
        return _mean([v for r in self.own + self.others for v in r.normalized_reward])

    @property
    def validation_success_rate(self) -> float:
        """Success rate on the curator's validation mazes (NaN without any)."""
        return _mean([s for r in self.validation for s in r.success])

    @property
    def validation_normalized_reward(self) -> float:
        """Mean R̄ on the curator's validation mazes (NaN without any)."""
        return _mean([v for r in self.validation for v in r.normalized_reward])

    def figures(self) -> dict[str, Any]:
        """The figures a decision record keeps of the candidate."""
        validation = (
            {
                "validation_success_rate": self.validation_success_rate,
                "validation_normalized_reward": self.validation_normalized_reward,
            }
            if self.validation
            else {}
        )
        return {
            **validation,
            "branch": self.branch,
            "success_rate": self.success_rate,
            "normalized_reward": self.normalized_reward,
            "overall_success_rate": self.overall_success_rate,
            "overall_normalized_reward": self.overall_normalized_reward,
            "env_steps": self.env_steps,
            "converged": self.converged,
        }


@dataclass(frozen=True)
class StageRecord:
    """A finished stage: its mazes, its candidates and the branch selected from it."""

    stage: int
    mazes: tuple[str, ...]
    candidates: tuple[Candidate, ...]
    selected: int | None = None


@dataclass(frozen=True)
class History:
    """The curriculum so far, as :meth:`Curator.generate` sees it."""

    #: The stage whose mazes are being generated (1 to ``stages - 1``).
    stage: int
    #: The candidate that was selected to go on: the parent of the new branches.
    parent: Candidate
    #: Every stage before this one, in order.
    stages: tuple[StageRecord, ...]

    @property
    def mazes(self) -> tuple[str, ...]:
        """The mazes the parent trained on."""
        return self.parent.mazes


@dataclass(frozen=True)
class CuratorContext:
    """What a curator is built from."""

    #: The maze the curriculum leads to (canonical string), the family's representative.
    target: str
    #: The run's seed: curators draw from :meth:`rng` only.
    seed: int
    stages: int
    branches: int
    robot: str = "DD"
    #: The curator's options (``curator_options`` of the run config).
    options: Mapping[str, Any] = field(default_factory=dict)
    #: The name of the curator's advisor, when it has one (``--advisor``; see
    #: :mod:`amaze.curriculum.advice`): it then gets a proposal at every decision.
    advisor: str | None = None
    #: ``"curator"`` for the deciding curator, ``"advisor"`` for an advisor: an
    #: advisor's streams (:meth:`rng`) are its own, apart from the decider's.
    role: str = "curator"

    def rng(self, stage: int, purpose: str) -> np.random.Generator:
        """A generator for one decision: derived from the run's seed, the stage and a purpose.

        The same question always gets the same stream, whatever was asked
        before it (a resumed run asks only the questions that remain). An
        advisor's context (``role`` ``"advisor"``) gives other streams than the
        decider's for the same question.
        """
        if self.role != "curator":
            purpose = f"{self.role}:{purpose}"
        words = [int(b) for b in purpose.encode("utf-8")]
        return np.random.default_rng(np.random.SeedSequence([self.seed, stage, 0x5EED, *words]))

    def trivial_maze(self) -> str:
        """The first maze of every curriculum: the interpolation's trivial start, 4 rotations."""
        from amaze.curriculum.interpolation import interpolation_start

        return interpolation_start(self.target).to_string()


@runtime_checkable
class Curator(Protocol):
    """Makes a curriculum's two decisions (see the module docstring)."""

    name: str

    def select(self, candidates: Sequence[Candidate]) -> Candidate:
        """The candidate that goes on (one of ``candidates``)."""
        ...

    def generate(self, k: int, history: History) -> list[str]:
        """``k`` maze strings for the next stage's branches."""
        ...


def _plugins() -> dict[str, Any]:
    """The curators declared by installed distributions (entry points), by name."""
    return _plugins_on(tuple(sys.path))


@functools.lru_cache(maxsize=8)
def _plugins_on(path: tuple[str, ...]) -> dict[str, Any]:
    """:func:`_plugins` for the import path ``path`` (scanned once: a study checks thousands)."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def curator_names() -> list[str]:
    """Every curator name: the built-in ones, then the installed plug-ins'."""
    return [*BUILTIN_CURATORS, *sorted(set(_plugins()) - set(BUILTIN_CURATORS))]


def curator_class(name: str) -> type:
    """The class of the curator called ``name`` (a built-in one or a plug-in's)."""
    if not isinstance(name, str):
        raise CuratorError(f"curator name {name!r} is not a string")
    if name in BUILTIN_CURATORS:
        module, _, attribute = BUILTIN_CURATORS[name].partition(":")
        return getattr(importlib.import_module(module), attribute)
    plugin = _plugins().get(name)
    if plugin is None:
        raise CuratorError(
            f"unknown curator {name!r} (choose from {', '.join(curator_names())},"
            f" or install one under the entry-point group {ENTRY_POINT_GROUP!r})"
        )
    try:
        loaded = plugin.load()
    except Exception as problem:  # a broken plug-in is the user's to fix: say which
        raise CuratorError(
            f"curator {name!r} ({plugin.value}) cannot be loaded: {problem}"
        ) from None
    if not isinstance(loaded, type):
        raise CuratorError(f"curator {name!r} ({plugin.value}) is not a class")
    return loaded


def make_curator(name: str, context: CuratorContext) -> Curator:
    """The curator called ``name``, built for ``context``."""
    cls = curator_class(name)
    curator = cls(context)
    if not isinstance(curator, Curator):
        raise CuratorError(
            f"curator {name!r} ({cls.__module__}.{cls.__qualname__}) lacks name, select or generate"
        )
    return curator


def refuse_unknown_options(context: CuratorContext, name: str, known: Sequence[str] = ()) -> None:
    """Refuse the options of ``context`` that the curator ``name`` does not read.

    An option no curator reads would have no effect: the message names it,
    and the curator as its role says (``curator`` or ``advisor``).
    """
    unknown = sorted(set(context.options) - set(known))
    if unknown:
        takes = f"known: {', '.join(known)}" if known else "it takes none"
        named = ", ".join(f"{key}{closest(key, known)}" for key in unknown)
        raise CuratorError(f"{context.role} {name!r}: unknown option(s) {named} ({takes})")


def check_mazes(mazes: Any, k: int, who: str) -> list[str]:
    """``k`` maze strings from a curator, canonical; raise :class:`CuratorError` otherwise."""
    from amaze.maze.spec import MazeSpec

    if isinstance(mazes, str) or not isinstance(mazes, Sequence) or len(mazes) != k:
        raise CuratorError(f"curator {who!r} generated {mazes!r}, not a list of {k} maze strings")
    checked = []
    for maze in mazes:
        try:
            checked.append(MazeSpec.from_string(str(maze)).to_string())
        except (ValueError, TypeError) as problem:
            raise CuratorError(
                f"curator {who!r} generated the bad maze {maze!r}: {problem}"
            ) from None
    rotations(checked)
    return checked

"""The regime fields of a trainer's config: what every regime of every trainer shares.

:class:`RegimeConfig` is the base of both trainers' configs
(``evolution.config.EvolveConfig``, ``rl_baselines.config.TrainConfig``): the
``regime`` and the fields of each regime (a curriculum's curator, stages,
branches, epochs, rehearsal and final training; a co-evolution's options; the
direct regime's mazes, evaluation mazes and agent rule; the target that
curricula and co-evolution lead to). Each field declares the regimes it acts
in (``option(regimes=...)``): set in another, the config is refused.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from dataclasses import dataclass
from typing import Any, ClassVar

from amaze.agents.robot import as_robot
from amaze.curriculum.advice import NOT_ADVISORS
from amaze.curriculum.curators import (
    CuratorContext,
    curator_names,
)
from amaze.curriculum.interpolation import MAX_STAGES
from amaze.curriculum.maze_population import CoevolutionError, MazePopulationConfig
from amaze.curriculum.population_selector import SelectorConfig
from amaze.curriculum.regimes import (
    COEVOLUTION_REGIMES,
    CURRICULUM_REGIMES,
    MAX_OPEN_STAGES,
    OPEN_EPOCHS,
    OPEN_STAGES,
    REGIMES,
)
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze.spec import MazeSpec
from amaze.runs.anytime import DEFAULT_FAMILY, DEFAULT_POINTS
from amaze.runs.config import RunConfig, option
from amaze.validation import check_integer

__all__ = ["MAX_BRANCHES", "MAX_REHEARSAL", "RegimeConfig"]

#: Most branches per stage.
MAX_BRANCHES = 64
#: The default numbers of stages and branches (the paper's S and K; EDEnS: open-ended).
DEFAULT_STAGES = {"edhucat": 10, "interpolation": 10, "edens": OPEN_STAGES}
DEFAULT_BRANCHES = {"edhucat": 3, "interpolation": 1, "edens": 3}
DEFAULT_CURATOR = {"edhucat": "careful", "interpolation": "interpolation", "edens": "edens"}
#: The default rehearsal: earlier lineage mazes a branch also trains on (the paper: none).
DEFAULT_REHEARSAL = {"edhucat": 0, "interpolation": 0, "edens": 7}
#: Most rehearsed mazes.
MAX_REHEARSAL = 64
#: Most anytime evaluations of a run, and most family mazes in their set.
MAX_POINTS = 1000
MAX_FAMILY = 1000


@dataclass
class RegimeConfig(RunConfig):
    """The regime fields of a trainer's config (``regime``, ``curator``, ``stages``...).

    Each field acts in some regimes (its ``regimes``, :func:`~amaze.runs.config.option`):
    set in another one, it is refused. In the direct regime ``curator``,
    ``stages`` and ``branches`` stay unset; in a curriculum regime
    :meth:`validate` fills them with the regime's defaults, so ``config.json``
    records what ran; in the direct regime it fills ``agent_rule`` and
    ``eval_mazes`` with the trainer's defaults.
    """

    #: The regimes this trainer runs: the direct and curriculum ones; a trainer
    #: with a loop of its own for another regime (``coevolution``) adds it.
    supported_regimes: ClassVar[tuple[str, ...]] = ("direct", *CURRICULUM_REGIMES)
    #: The trainer's default ``epochs`` of an open-ended curriculum.
    default_epochs: ClassVar[int] = OPEN_EPOCHS
    #: The rules that may choose a direct run's agent, the trainer's default first.
    agent_rules: ClassVar[tuple[str, ...]] = ("final", "best-eval")
    #: The evaluation mazes of a direct run when the config gives none.
    default_eval_mazes: ClassVar[tuple[str, ...]] = ()

    regime: str = option("direct", "training regime", choices=REGIMES)
    curator: str | None = option(
        None,
        "who selects agents and generates mazes in the edhucat regime: careful, moderate,"
        " risky, random, edens, human, interpolation or a plug-in's name (default: careful)",
        metavar="NAME",
        regimes=CURRICULUM_REGIMES,
    )
    stages: int | None = option(
        None,
        "curriculum stages S, the trivial first one included; 0: open-ended, stages until"
        " the budget is spent (default: 10; 0 for edens)",
        metavar="S",
        regimes=CURRICULUM_REGIMES,
    )
    branches: int | None = option(
        None,
        "branches K per stage (default: 3 for edhucat and edens, 1 for interpolation)",
        metavar="K",
        regimes=CURRICULUM_REGIMES,
    )
    epochs: int | None = option(
        None,
        "an open-ended curriculum's epochs: each branch may spend budget / (K * epochs)"
        " (default: 100 for evolution, 10 for RL)",
        metavar="E",
        regimes=CURRICULUM_REGIMES,
    )
    rehearsal: int | None = option(
        None,
        "earlier mazes of the lineage each branch also trains on, besides its own"
        " (default: 7 for edens, 0 otherwise)",
        metavar="R",
        regimes=CURRICULUM_REGIMES,
    )
    target: str = option(
        PAPER_TRAINING_MAZE,
        "the maze a curriculum or a co-evolution leads to (interpolation's end, the"
        " curators' target, the family of the co-evolved mazes)",
        metavar="MAZE",
        regimes=(*CURRICULUM_REGIMES, *COEVOLUTION_REGIMES),
    )
    mazes: list[str] = option(
        default_factory=lambda: [PAPER_TRAINING_MAZE],
        help="training mazes of the direct regime, each played in its 4 rotations"
        " (default: the paper's)",
        regimes=("direct",),
    )
    eval_mazes: list[str] | None = option(
        None,
        "mazes a direct run evaluates its agent on as it trains, 4 rotations each"
        " (default: the paper's evaluation maze for RL, none for evolution)",
        regimes=("direct",),
    )
    agent_rule: str | None = option(
        None,
        "which agent a direct run hands over: final (the agent when training stops),"
        " best-eval (the best on eval_mazes among the evaluations), best-fitness"
        " (evolution: the best training fitness) (default: final for RL, best-fitness"
        " for evolution; curricula hand over the curator's final choice, co-evolution"
        " the best on its validation mazes)",
        metavar="RULE",
        regimes=("direct",),
    )
    final_training: bool = option(
        True,
        "spend what the stages leave of the budget on the final agent, trained on its"
        " lineage's mazes (off: the paper's protocol, the final choice as it is)",
        regimes=CURRICULUM_REGIMES,
    )
    curator_options: dict[str, Any] = option(
        default_factory=dict,
        help="the curator's own options (--curator-option KEY=VALUE)",
        command_line=False,
        regimes=CURRICULUM_REGIMES,
    )
    advisor: str | None = option(
        None,
        "an automated curator (edens, careful... or a plug-in's) that advises the curator:"
        " at each decision its proposal comes first, is shown to the curator and recorded"
        " with whether it was accepted (human, follow and the shipped curators take advice)",
        metavar="NAME",
        regimes=("edhucat",),
    )
    advisor_options: dict[str, Any] = option(
        default_factory=dict,
        help="the advisor's own options (--advisor-option KEY=VALUE)",
        command_line=False,
        regimes=("edhucat",),
    )
    replay: str | None = option(
        None,
        "the run whose recorded decisions this run replays",
        command_line=False,
        regimes=(*CURRICULUM_REGIMES, "edens-populations"),
    )
    coevolution: dict[str, Any] = option(
        default_factory=dict,
        help="the maze population's options in the coevolution regimes (MazePopulationConfig;"
        " in edens-populations, the first epoch's controller)",
        command_line=False,
        regimes=COEVOLUTION_REGIMES,
    )
    selector: dict[str, Any] = option(
        default_factory=dict,
        help="the EDEnS selector's options in the edens-populations regime (SelectorConfig:"
        " alternatives, epoch, mutations, criteria)",
        command_line=False,
        regimes=("edens-populations",),
    )
    evaluation_points: int = option(
        DEFAULT_POINTS,
        "anytime evaluations: the agent the run would hand over, played on the evaluation"
        " set at N evenly spaced fractions of the budget (evaluations.csv); 0: none",
        metavar="N",
    )
    evaluation_family: int = option(
        DEFAULT_FAMILY,
        "family mazes (new seeds) in the evaluation set of the anytime evaluations,"
        " besides the training mazes; 4 rotations each",
        metavar="N",
    )
    evaluation_maze: str | None = option(
        None,
        "the maze whose family the evaluation set of a direct run draws from, and which"
        " it holds instead of the training mazes (default: the first training maze's"
        " family, and the training mazes): a curriculum's target puts a direct run on"
        " family mazes (domain randomisation) on the curricula's evaluation set",
        metavar="MAZE",
        regimes=("direct",),
    )

    @property
    def is_curriculum(self) -> bool:
        """True for the regimes the curriculum loop plays."""
        return self.regime in CURRICULUM_REGIMES

    @property
    def open_ended(self) -> bool:
        """True for a curriculum whose stages go on until the budget is spent."""
        return self.is_curriculum and self.stages == OPEN_STAGES

    def validate(self) -> RegimeConfig:
        """Check the regime fields (and the shared ones); fill a curriculum's defaults."""
        super().validate()
        if self.regime not in self.supported_regimes:
            known = "is not run by this trainer" if self.regime in REGIMES else "is unknown"
            raise self.error(
                f"regime {self.regime!r} {known} (choose from {', '.join(self.supported_regimes)})"
            )
        self.refuse_options_without_effect(self.regime)  # before anything is normalised
        self.evaluation_points = check_integer(
            "evaluation_points", self.evaluation_points, minimum=0, maximum=MAX_POINTS,
            error=self.error,
        )  # fmt: skip
        self.evaluation_family = check_integer(
            "evaluation_family", self.evaluation_family, minimum=0, maximum=MAX_FAMILY,
            error=self.error,
        )  # fmt: skip
        if self.regime != "direct":
            self.target = self._maze("target", self.target)
        self.mazes = self._maze_list("mazes", self.mazes)
        if self.evaluation_maze is not None:
            self.evaluation_maze = self._maze("evaluation_maze", self.evaluation_maze)
        if self.eval_mazes is not None:
            self.eval_mazes = self._maze_list("eval_mazes", self.eval_mazes, empty=True)
        self._check_coevolution()
        if self.replay is not None and not isinstance(self.replay, str):
            raise self.error(f"replay {self.replay!r} is not a run folder")
        if self.regime == "direct":
            self._direct_defaults()
        if not self.is_curriculum:
            return self
        if self.curator is None:
            self.curator = DEFAULT_CURATOR[self.regime]
        own = DEFAULT_CURATOR[self.regime]
        if self.regime != "edhucat" and self.curator != own:
            raise self.error(
                f"curator {self.curator!r}: the {self.regime} regime's curator is {own}"
                " (use --regime edhucat for another curator)"
            )
        if not isinstance(self.curator, str) or self.curator not in curator_names():
            raise self.error(
                f"unknown curator {self.curator!r} (choose from {', '.join(curator_names())})"
            )
        if self.stages is None:
            self.stages = DEFAULT_STAGES[self.regime]
        if self.branches is None:
            self.branches = DEFAULT_BRANCHES[self.regime]
        if self.rehearsal is None:
            self.rehearsal = DEFAULT_REHEARSAL[self.regime]
        self.stages = check_integer(
            "stages", self.stages, minimum=0, maximum=MAX_STAGES, error=self.error
        )
        if self.regime == "interpolation" and self.stages < 2:
            raise self.error(
                f"stages {self.stages}: an interpolation has a fixed number of stages, 2 or"
                " more (its first maze and its target)"
            )
        if self.stages != OPEN_STAGES and self.epochs is not None:
            raise self.error(
                f"epochs {self.epochs!r} is for open-ended curricula (stages 0), not"
                f" {self.stages} stages"
            )
        if self.stages == OPEN_STAGES:
            if self.epochs is None:
                self.epochs = self.default_epochs
            self.epochs = check_integer(
                "epochs", self.epochs, minimum=1, maximum=MAX_OPEN_STAGES, error=self.error
            )
        self.rehearsal = check_integer(
            "rehearsal", self.rehearsal, minimum=0, maximum=MAX_REHEARSAL, error=self.error
        )
        self.branches = check_integer(
            "branches", self.branches, minimum=1, maximum=MAX_BRANCHES, error=self.error
        )
        if not isinstance(self.curator_options, dict):
            raise self.error(f"curator_options {self.curator_options!r} is not a JSON object")
        self._check_advisor()
        return self

    def _check_advisor(self) -> None:
        """An advisor is an automated curator; ``follow`` needs one; its options need it."""
        if not isinstance(self.advisor_options, dict):
            raise self.error(f"advisor_options {self.advisor_options!r} is not a JSON object")
        if self.advisor is None:
            if self.curator == "follow":
                raise self.error(
                    "curator 'follow' follows an advisor's proposals: give it one"
                    " (--advisor NAME, e.g. --advisor edens)"
                )
            if self.advisor_options:
                raise self.error(
                    f"advisor_options {self.advisor_options!r} without an advisor (--advisor NAME)"
                )
            return
        if not isinstance(self.advisor, str) or self.advisor not in curator_names():
            raise self.error(
                f"unknown advisor {self.advisor!r} (choose from an automated curator:"
                f" {', '.join(n for n in curator_names() if n not in NOT_ADVISORS)})"
            )
        if self.advisor in NOT_ADVISORS:
            raise self.error(
                f"advisor {self.advisor!r} cannot advise: an advisor is an automated curator"
                f" that makes its proposal alone (not {' or '.join(NOT_ADVISORS)})"
            )
        if self.stages == 1:
            raise self.error(
                f"advisor {self.advisor!r} has no effect with 1 stage: the curator makes no"
                " decision (the first stage's maze is the trivial one and its one branch is"
                " chosen); give --stages 2 or more, or leave --advisor out"
            )

    def _maze(self, name: str, value: Any) -> str:
        """``value``'s canonical maze string; the config's error naming ``name`` otherwise."""
        try:
            return MazeSpec.from_string(str(value)).to_string()
        except ValueError as problem:
            raise self.error(f"{name} {value!r}: {problem}") from None

    def _maze_list(self, name: str, value: Any, empty: bool = False) -> list[str]:
        """A list of maze strings, each checked (a comma-separated string is split).

        The strings are kept as given (``config.json`` records what the user
        wrote; the trainers parse them).
        """
        if isinstance(value, str):
            value = [m.strip() for m in value.split(",") if m.strip()]
        if not isinstance(value, list) or (not value and not empty):
            raise self.error(f"{name} {value!r} is not a non-empty list of maze strings")
        for maze in value:
            self._maze(name, maze)
        return list(value)

    def _direct_defaults(self) -> None:
        """A direct run's agent rule and evaluation mazes: the config's or the trainer's."""
        if self.agent_rule is None:
            self.agent_rule = self.agent_rules[0]
        if self.agent_rule not in self.agent_rules:
            raise self.error(
                f"agent_rule {self.agent_rule!r} is not one of {', '.join(self.agent_rules)}"
            )
        if self.eval_mazes is None:
            self.eval_mazes = list(self.default_eval_mazes)
        if self.agent_rule in ("best-eval", "best-eval-reward") and not self.eval_mazes:
            raise self.error(
                f"agent_rule {self.agent_rule!r} needs eval_mazes (--eval-mazes A,B,...)"
            )

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """The config's options, and ``--curator-option`` / ``--advisor-option KEY=VALUE``."""
        super().add_arguments(parser)
        for who in ("curator", "advisor"):
            parser.add_argument(
                f"--{who}-option",
                action="append",
                metavar="KEY=VALUE",
                dest=f"{who}_option",
                help=f"one of the {who}'s options (repeatable; VALUE is read as JSON when it"
                f" can be: p=0.5, base=careful, directed=false), into {who}_options",
            )

    @classmethod
    def adjust_command_line(cls, data: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
        """``--budget-seconds`` without ``--budget-steps`` is a wall-clock budget alone.

        (A trainer's default ``budget_steps`` would otherwise limit it too.) A
        ``--config`` file that sets ``budget_steps`` keeps it: both budgets apply.
        ``--curator-option`` and ``--advisor-option`` add to the file's options.
        """
        if getattr(args, "budget_seconds", None) is not None and args.budget_steps is None:
            data.setdefault("budget_steps", None)
        for who in ("curator", "advisor"):
            given = getattr(args, f"{who}_option", None)
            if given:
                options = data.get(f"{who}_options", {})
                options = dict(options) if isinstance(options, dict) else {}
                data[f"{who}_options"] = {**options, **cls._key_values(f"--{who}-option", given)}
        return data

    @classmethod
    def given_extra_options(cls, args: argparse.Namespace) -> list[str]:
        """The flags of :meth:`add_arguments` given on the command line."""
        flags = super().given_extra_options(args)
        given = [who for who in ("curator", "advisor") if getattr(args, f"{who}_option", None)]
        return flags + [f"--{who}-option" for who in given]

    @classmethod
    def _key_values(cls, flag: str, items: list[str]) -> dict[str, Any]:
        """``KEY=VALUE`` items as a dict; a VALUE that is JSON is read as JSON, else as text."""
        options: dict[str, Any] = {}
        for item in items:
            key, equals, text = item.partition("=")
            if not equals or not key.strip():
                raise cls.error(f"{flag} {item!r} is not KEY=VALUE")
            try:
                value = json.loads(text)
            except ValueError:
                value = text
            options[key.strip()] = value
        return options

    def coevolution_defaults(self) -> dict[str, Any]:
        """The maze population options this trainer fills in when the config leaves them out.

        None here: :class:`~amaze.curriculum.maze_population.MazePopulationConfig`'s
        own defaults apply. A trainer whose batch follows from its own options
        (RL: one environment per rotation of each batch maze) gives them.
        """
        return {}

    def check_coevolution_options(self, options: MazePopulationConfig) -> None:
        """Refuse population ``options`` this trainer cannot run (any, here)."""

    def _check_coevolution(self) -> None:
        """The co-evolution configs, checked here alone: ``coevolution``, ``selector``, the fit.

        ``coevolution`` and ``selector`` are JSON objects (set in another
        regime, they were refused with the other options there). In the
        coevolution regimes the trainer's defaults (:meth:`coevolution_defaults`)
        fill what ``coevolution`` leaves out (``config.json`` then records
        them); the whole is a valid
        :class:`~amaze.curriculum.maze_population.MazePopulationConfig`, which the
        robot (``shapes`` need an image robot) and the trainer's options must fit
        (:meth:`check_coevolution_options`); in ``edens-populations`` the
        ``selector`` is a valid
        :class:`~amaze.curriculum.population_selector.SelectorConfig`, recorded
        with its defaults.
        """
        for name in ("coevolution", "selector"):
            if not isinstance(getattr(self, name), dict):
                raise self.error(f"{name} {getattr(self, name)!r} is not a JSON object")
        if self.regime not in COEVOLUTION_REGIMES:
            return  # options set here were refused with the other options of other regimes
        options = {**self.coevolution_defaults(), **self.coevolution}
        try:
            checked = MazePopulationConfig.from_dict(options)
            if self.regime == "edens-populations":
                self.selector = SelectorConfig.from_dict(self.selector).to_dict()
        except CoevolutionError as problem:
            raise self.error(str(problem)) from None
        if checked.drawn_shapes is not None and as_robot(self.robot).discrete_inputs:
            named = (
                f"shapes {list(checked.shapes)!r}"
                if checked.shapes is not None
                else f"sign_styles {checked.sign_styles}"
            )
            raise self.error(
                f"coevolution {named} have no effect for robot {self.robot}: it reads sign"
                " values, not their images (give an H robot)"
            )
        self.check_coevolution_options(checked)
        self.coevolution = options

    def curator_context(self) -> CuratorContext:
        """What the curator is built from."""
        assert self.stages is not None and self.branches is not None
        return CuratorContext(
            target=self.target,
            seed=self.seed,
            stages=self.stages,
            branches=self.branches,
            robot=self.robot,
            options=dict(self.curator_options),
            advisor=self.advisor,
        )

    def advisor_context(self) -> CuratorContext:
        """What the advisor is built from: its options, and streams apart from the curator's."""
        return dataclasses.replace(
            self.curator_context(),
            options=dict(self.advisor_options),
            advisor=None,
            role="advisor",
        )

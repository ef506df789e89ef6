"""Studies as files: a grid of trainers x algorithms x budgets x seeds, in TOML.

A study names the runs of a comparison. ``experiments/studies/`` ships those
of ``docs/studies.md``; any TOML file of this form is a study::

    name = "mine"
    description = "PPO against CMA-ES on the paper's three trainers"
    seeds = 5                         # seeds 0..4; or a list: seeds = [3, 7]
    robot = "DD"                      # or several: robot = ["DD", "H15"]
    trainers = ["direct", "interpolation", "edhucat-careful"]
    algorithms = ["ppo", "ppo-fast", "cmaes"]  # an algorithm, or a variant of one (below)
    suite = "standard"                # the final agents' scores in the report: the
                                      #   standard suite, or "paper" (Table 3's suite)

    [variants]                        # algorithms at settings of their own: name = base
    ppo-fast = "ppo"

    [budgets]                         # each budget is a treatment of its own
    steps = { steps = 1_000_000 }     # env steps
    clock = { seconds = 600 }         # wall-clock seconds (steps = ... too: whichever first)

    [options.all]                     # config fields of every run where they act (target:
                                      #   the curricula's), then more specific ones:
    [options.ppo]                     #   an algorithm's,
    hyperparameters = { n_steps = 512 }
    [options.edhucat-careful]         #   a trainer's,
    stages = 5
    [options."coevolution/ppo"]       #   a trainer/algorithm pair's (the last word)
    n_envs = 16
    [options.ppo-fast]                #   a variant's: its own, not [options.ppo]'s
    framework = "jax"
    n_envs = 64
    hyperparameters = { n_steps = 64, batch_size = 1024, n_epochs = 4 }

    [[exclude]]                       # cells of the grid left out
    trainer = "coevolution"
    algorithm = "neat"

    [[comparisons]]                   # what the report draws and tests (see below)
    name = "regimes-ppo"              # letters, digits, dashes: the figures' file names
    title = "Regimes with PPO"        # optional
    budget = "steps"                  # one of [budgets]; optional when there is one
    treatments = ["direct/ppo", "interpolation/ppo", "edhucat-careful/ppo"]  # 1 to 8 cells
    pairs = [["interpolation/ppo", "direct/ppo"]]  # probability of improvement of each

A *treatment* is a (trainer, algorithm, condition) cell, the condition being
the budget (and the robot, when the study has several), run once per seed.
Reading a study checks it whole, so that a bad one fails before anything runs,
naming the file and the run: first what costs nothing, the file's size
(:data:`MAX_STUDY_BYTES`) and nesting (:data:`MAX_DEPTH`), the seeds
(``0 .. 2**32 - 1``), the number of runs counted from the grid
(:data:`MAX_RUNS`), printable names and titles, short ASCII budget and
comparison names (they become file names and CSV cells); then every run's
config, built by its trainer's config class, and its curator options.

A *comparison* is one figure of the report: up to :data:`MAX_LINES` cells under
one ``budget``, and the ``pairs`` whose probability of improvement the report
gives (by default the pairs that differ in one factor, else every pair;
``pairs = []``: none). ``robot`` picks one of the study's robots; without it a
study of several robots gets the comparison once per robot (``name-robot``).
Without ``[[comparisons]]``, a study gets :func:`default_comparisons`.

An algorithm *variant* (``[variants]``: :func:`~experiments.trainers.parse_variants`)
is an algorithm at settings of its own (PPO at SB3's defaults beside PPO at a
throughput setting): its name goes wherever an algorithm's does, and
``runs.csv``, the run folders and the report show it. Its runs are its base's
(the config's ``algo``, run class and checks) with the options given under its
own name, not the base's (``[options.ppo]``): a variant is a treatment of its own.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path
from typing import Any

from amaze.errors import AmazeError, UsageError, one_line
from amaze.runs.config import MAX_SEED
from amaze.validation import closest, nests_within
from experiments.comparisons import (
    MAX_LINES,
    NAME_RULE,
    Grid,
    StudyComparison,
    default_comparisons,
    is_name,
    is_text,
    key_shown,
    parse_comparisons,
)
from experiments.trainers import (
    ALGORITHMS,
    EVOLUTION_ALGORITHMS,
    TRAINERS,
    parse_variants,
    run_class,
    trainer_fields,
)

__all__ = [
    "MAX_LINES",
    "STUDIES",
    "PlannedRun",
    "Study",
    "StudyComparison",
    "StudyError",
    "default_comparisons",
    "load_study",
    "study_names",
]

#: The folder of the shipped studies.
STUDIES = files("experiments") / "studies"
#: The keys a study file may have.
STUDY_KEYS = frozenset(
    {"name", "description", "seeds", "robot", "trainers", "algorithms", "budgets", "options"}
    | {"exclude", "comparisons", "suite", "variants"}
)

#: The suites a study's report may score its final agents on (``suite`` in the study file).
SUITES = ("standard", "paper")
#: Most runs in one study.
MAX_RUNS = 10_000
#: Deepest nesting of tables and arrays in a study file. A study nests a few
#: levels (``options.ppo.hyperparameters``); its runs' configs are JSON files,
#: read back with a limit of their own (:data:`amaze.validation.MAX_JSON_DEPTH`).
MAX_DEPTH = 32
#: Largest study file, in bytes (the shipped ones hold a few kilobytes).
MAX_STUDY_BYTES = 2**20
#: Longest study name (a heading of the report, a cell of ``runs.csv``).
MAX_NAME = 200
#: Largest steps budget: 2**53, the largest count a float holds exactly (the report's shares).
MAX_BUDGET_STEPS = 2**53
#: Longest message of a run's config check (one may list every unknown key).
MAX_PROBLEM = 500

#: How a value's problem becomes the error naming the study file.
Bad = Callable[[str], "StudyError"]


class StudyError(AmazeError):
    """A study file that cannot be run: the message names the file and the value."""


@dataclass(frozen=True)
class PlannedRun:
    """One run of a study: its treatment, its seed and its whole checked config."""

    trainer: str
    algorithm: str
    budget: str
    seed: int
    config: dict[str, Any] = field(compare=False)
    #: The robot, when the study has several (else ``None``: the study's one robot).
    robot: str | None = None

    @property
    def condition(self) -> str:
        """The budget's name, with the robot when the study has several (``steps-H15``)."""
        return self.budget if self.robot is None else f"{self.budget}-{self.robot}"

    @property
    def treatment(self) -> str:
        """``trainer/algorithm/condition``: the cell of the grid."""
        return f"{self.trainer}/{self.algorithm}/{self.condition}"

    @property
    def id(self) -> str:
        """A name unique in the study, also the run's folder under ``runs/``."""
        return f"{self.trainer}_{self.algorithm}_{self.condition}_seed-{self.seed}"

    @property
    def cell(self) -> str:
        """``trainer/algorithm``: the treatment without its condition (one colour in figures)."""
        return f"{self.trainer}/{self.algorithm}"

    @property
    def base_algorithm(self) -> str:
        """The algorithm that trains the run (its config's ``algo``): ``algorithm`` itself, or
        the base of a variant (``ppo`` for ``ppo-fast``)."""
        return self.config["algo"]

    @property
    def budget_unit(self) -> str | None:
        """What the run's budget counts: ``"steps"`` when it has a steps budget, else ``"seconds"``.

        As the anytime evaluations divide it (:mod:`amaze.runs.anytime`).
        """
        if self.budget_steps is not None:
            return "steps"
        return "seconds" if self.budget_seconds is not None else None

    @property
    def budget_steps(self) -> int | None:
        return self.config.get("budget_steps")

    @property
    def budget_seconds(self) -> float | None:
        return self.config.get("budget_seconds")


@dataclass(frozen=True)
class Study:
    """A study read from its TOML file (see the module docstring)."""

    name: str
    description: str
    source: str
    text: str
    runs: tuple[PlannedRun, ...]
    #: What the report compares: the file's ``[[comparisons]]``, else :func:`default_comparisons`.
    comparisons: tuple[StudyComparison, ...] = ()
    #: The suite the report scores the final agents on: ``standard`` or ``paper`` (the
    #: paper's Table 3 suite); ``runs.csv`` holds both.
    suite: str = "standard"

    @property
    def treatments(self) -> list[str]:
        """The treatments, in the file's order."""
        return list(dict.fromkeys(run.treatment for run in self.runs))

    @property
    def variants(self) -> dict[str, str]:
        """The algorithm variants that have runs, each with its base: ``{"ppo-fast": "ppo"}``."""
        return {r.algorithm: r.base_algorithm for r in self.runs if r.algorithm != r.base_algorithm}

    @property
    def conditions(self) -> list[str]:
        """The conditions (budgets, with the robot when there are several), in the file's order."""
        return list(dict.fromkeys(run.condition for run in self.runs))


def study_names() -> list[str]:
    """The shipped studies' names."""
    return sorted(
        p.name.removesuffix(".toml") for p in STUDIES.iterdir() if p.name.endswith(".toml")
    )


def load_study(name_or_path: str | Path) -> Study:
    """The study called ``name_or_path`` (a shipped one) or in that TOML file, checked."""
    text_name = str(name_or_path)
    shipped = STUDIES / f"{text_name}.toml"
    if not text_name.endswith(".toml") and shipped.is_file():
        source, text = f"study {text_name!r}", shipped.read_text(encoding="utf-8")
    else:
        path = Path(text_name)
        if not path.is_file():
            raise UsageError(
                f"no study {text_name!r}: neither a file nor one of {', '.join(study_names())}"
            )
        source = f"study file {text_name!r}"
        text = read_study_text(path, source)
    return parse_study(text, source)


def read_study_text(path: Path, source: str) -> str:
    """The text of the study file ``path``; :class:`StudyError` naming ``source`` otherwise.

    A file of more than :data:`MAX_STUDY_BYTES` is refused before it is read whole.
    """
    try:
        with path.open("rb") as stream:
            data = stream.read(MAX_STUDY_BYTES + 1)
    except OSError as problem:
        raise StudyError(f"{source} cannot be read: {problem.strerror or problem}") from None
    if len(data) > MAX_STUDY_BYTES:
        raise StudyError(f"{source} holds more than the {MAX_STUDY_BYTES:,} bytes a study may")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as problem:
        raise StudyError(
            f"{source} is not UTF-8 text ({problem.reason} at byte {problem.start})"
        ) from None


def parse_study(text: str, source: str = "study") -> Study:
    """The study in the TOML ``text``.

    Args:
        text: the study file's text (``amaze-experiment run`` takes such files).
        source: what names the text in error messages.

    Returns:
        The study, its planned runs (trainers x algorithms x budgets x seeds) and
            comparisons.

    Raises:
        StudyError: a key, value or file the study cannot hold, named.
    """

    def bad(message: str) -> StudyError:
        return StudyError(f"{source}: {message}")

    data = _toml(text, source, bad)
    unknown = set(data) - STUDY_KEYS
    if unknown:
        raise bad(
            "unknown key(s) "
            + ", ".join(key_shown(k) + closest(k, STUDY_KEYS) for k in sorted(unknown))
            + f" (known: {', '.join(sorted(STUDY_KEYS))})"
        )
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        raise bad(f"name {_shown(name)} is not a non-empty string")
    if len(name) > MAX_NAME:
        raise bad(f"name {_shown(name)} is longer than {MAX_NAME} characters")
    if not is_text(name):
        raise bad(f"name {_shown(name)} holds control characters")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise bad(f"description {_shown(description)} is not a string")
    if not is_text(description, lines=True):
        raise bad(f"description {_shown(description)} holds control characters")
    seeds = _seeds(data.get("seeds", 1), bad)
    suite = data.get("suite", "standard")
    if suite not in SUITES:
        raise bad(f"suite {_shown(suite)} is not one of {', '.join(SUITES)}")
    robots = _robots(data.get("robot", "DD"), bad)
    trainers = _names(data.get("trainers"), "trainers", TRAINERS, bad)
    variants = parse_variants(data.get("variants", {}), bad)
    algorithms = _names(data.get("algorithms"), "algorithms", [*ALGORITHMS, *variants], bad)
    unused = [name for name in variants if name not in algorithms]
    if unused:
        raise bad(f"variants: {', '.join(map(repr, unused))} declared but not in algorithms")
    budgets = _budgets(data.get("budgets"), bad)
    excluded = _excluded(data.get("exclude", []), bad)
    cells = [(t, a) for t in trainers for a in algorithms if (t, a) not in excluded]
    _check_size(len(robots), len(budgets), len(cells), len(seeds), bad)
    grid = Grid(tuple(budgets), tuple(robots), tuple(cells))
    comparisons = parse_comparisons(data.get("comparisons", []), grid, bad)
    options = _options(data.get("options", {}), [*ALGORITHMS, *variants], bad)
    curators = _CuratorCheck(bad)
    runs = []
    for robot in robots:
        shown = robot if len(robots) > 1 else None
        for budget_name, budget in budgets.items():
            for trainer, algorithm in cells:
                for seed in seeds:
                    base = variants.get(algorithm, algorithm)
                    config = _config(trainer, algorithm, base, budget, robot, seed, options)
                    run = PlannedRun(trainer, algorithm, budget_name, seed, config, shown)
                    runs.append(_checked(run, bad, curators))
    comparisons = comparisons or default_comparisons(grid)
    return Study(name.strip(), description, source, text, tuple(runs), comparisons, suite)


def _toml(text: str, source: str, bad: Bad) -> dict[str, Any]:
    """The TOML document ``text``, nested at most :data:`MAX_DEPTH` deep."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as problem:
        raise StudyError(f"{source} is not valid TOML: {problem}") from None
    except ValueError as problem:  # an integer of more digits than Python converts
        reason = one_line(problem).split("; use sys.")[0]  # not the hint to Python programmers
        raise StudyError(f"{source} is not valid TOML: {reason}") from None
    except RecursionError:  # the parser recurses once per level
        raise bad(f"tables or arrays nest more than {MAX_DEPTH} deep") from None
    if not nests_within(data, MAX_DEPTH):
        raise bad(f"tables or arrays nest more than {MAX_DEPTH} deep")
    return data


def _check_size(robots: int, budgets: int, cells: int, seeds: int, bad: Bad) -> None:
    """Refuse an empty grid, or one of more than :data:`MAX_RUNS` runs, before building any."""
    if not cells:
        raise bad("the grid holds no run (every cell is excluded)")
    count = robots * budgets * cells * seeds
    if count > MAX_RUNS:
        raise bad(
            f"{count:,} runs ({robots} robot(s) x {budgets} budget(s) x {cells} trainer/algorithm"
            f" cell(s) x {seeds} seed(s)): a study holds at most {MAX_RUNS:,}"
        )


def _seeds(value: Any, bad: Bad) -> list[int]:
    """Seeds ``0 .. value - 1`` (a number of replicates), or the list of seeds given."""
    if isinstance(value, int) and not isinstance(value, bool):
        if not 1 <= value <= 1000:
            raise bad(f"seeds {_shown(value)} is not in 1..1000 (replicates)")
        return list(range(value))
    if (
        isinstance(value, list)
        and value
        and all(isinstance(s, int) and not isinstance(s, bool) for s in value)
    ):
        for seed in value:
            if not 0 <= seed <= MAX_SEED:
                raise bad(f"seed {_shown(seed)} is not in 0..{MAX_SEED} (2**32 - 1)")
        if len(set(value)) != len(value):
            raise bad(f"seeds {_shown(value)} repeats a seed")
        return list(value)
    raise bad(f"seeds {_shown(value)} is neither a number of replicates nor a list of seeds")


def _problem(problem: Exception) -> str:
    """A config check's message on one line, cut to :data:`MAX_PROBLEM` characters."""
    text = one_line(problem)
    return text if len(text) <= MAX_PROBLEM else f"{text[: MAX_PROBLEM - 3]}..."


def _shown(value: Any, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters: a message names a value, not a whole list."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 5]}...{text[-1]}"


def _robots(value: Any, bad: Bad) -> list[str]:
    """The study's robots: one robot string or a list of distinct ones."""
    robots = [value] if isinstance(value, str) else value
    if not isinstance(robots, list) or not robots or not all(isinstance(r, str) for r in robots):
        raise bad(f"robot {_shown(value)} is not a robot or a list of robots")
    if len(set(robots)) != len(robots):
        raise bad(f"robot {robots} names one twice")
    return robots


def _names(value: Any, what: str, known: Any, bad: Bad) -> list[str]:
    if not isinstance(value, list) or not value:
        raise bad(f"{what} {_shown(value)} is not a non-empty list")
    for name in value:
        if not isinstance(name, str) or name not in known:
            raise bad(f"{what}: {_shown(name)} is not one of {', '.join(known)}")
    if len(set(value)) != len(value):
        raise bad(f"{what} {value} names one twice")
    return list(value)


def _budgets(value: Any, bad: Bad) -> dict[str, dict[str, Any]]:
    if not isinstance(value, dict) or not value:
        raise bad(f"budgets {_shown(value)} is not a table of named budgets")
    budgets = {}
    for name, budget in value.items():
        if not is_name(name):
            raise bad(f"budget name {_shown(name)} is not {NAME_RULE}")
        if not isinstance(budget, dict) or not budget or set(budget) - {"steps", "seconds"}:
            raise bad(f"budget {name!r} = {_shown(budget)} is not a table of steps and/or seconds")
        steps = budget.get("steps")
        if isinstance(steps, int) and steps > MAX_BUDGET_STEPS:
            raise bad(f"budget {name!r}: steps {_shown(steps)} is more than {MAX_BUDGET_STEPS:,}")
        # Seconds alone: no step limit (a trainer's default budget_steps would be one).
        fields = {"budget_steps": budget.get("steps")}
        if "seconds" in budget:
            fields["budget_seconds"] = budget["seconds"]
        budgets[name] = fields
    return budgets


def _options(value: Any, algorithms: list[str], bad: Bad) -> dict[str, Any]:
    """The ``[options]`` tables, keyed by ``all``, a trainer, one of ``algorithms`` (variants
    included) or a ``trainer/algorithm`` pair."""
    if not isinstance(value, dict):
        raise bad(f"options {_shown(value)} is not a table")
    for key, table in value.items():
        trainer, _, algorithm = key.partition("/")
        known = key == "all" or key in TRAINERS or key in algorithms
        known = known or (trainer in TRAINERS and algorithm in algorithms)
        if not known:
            raise bad(
                f"options.{key_shown(key)}: not 'all', a trainer, an algorithm (or a variant)"
                " or a trainer/algorithm pair"
            )
        if not isinstance(table, dict):
            raise bad(f"options.{key} {_shown(table)} is not a table")
        for reserved in ("seed", "algo", "regime", "curator", "robot"):
            if reserved in table:
                raise bad(f"options.{key} sets {reserved!r}, which the study's grid decides")
    return value


def _excluded(value: Any, bad: Bad) -> set[tuple[str, str]]:
    if not isinstance(value, list) or not all(
        isinstance(e, dict)
        and set(e) == {"trainer", "algorithm"}
        and all(isinstance(name, str) for name in e.values())
        for e in value
    ):
        raise bad(f"exclude {_shown(value)} is not a list of {{trainer, algorithm}} tables")
    return {(e["trainer"], e["algorithm"]) for e in value}


def _merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` updated with ``extra``; nested tables (hyperparameters...) merge key by key."""
    merged = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
            merged[key] = _merge(dict(merged[key]), value)
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def _config(
    trainer: str,
    algorithm: str,
    base: str,
    budget: dict[str, Any],
    robot: str,
    seed: int,
    options: dict[str, Any],
) -> dict[str, Any]:
    """The config of a run of ``trainer`` with ``algorithm`` (a variant of ``base``, or
    ``base`` itself): ``[options.all]``'s, then the trainer's, the algorithm's and the pair's."""
    config: dict[str, Any] = {"algo": base, "robot": robot, "seed": seed}
    config.update(trainer_fields(trainer))
    config.update(budget)
    shared = _acting(options.get("all", {}), base, config.get("regime", "direct"))
    config = _merge(config, shared)
    for key in (trainer, algorithm, f"{trainer}/{algorithm}"):
        config = _merge(config, options.get(key, {}))
    return config


def _acting(options: dict[str, Any], algorithm: str, regime: str) -> dict[str, Any]:
    """The options of ``[options.all]`` that act in ``regime`` for ``algorithm``'s trainer.

    ``all`` is said of every run of a study (``target``: the curricula's and
    co-evolution's target), so each run takes the options that act in its
    regime (the fields' ``regimes``); an option set for a trainer, an
    algorithm or a pair is that run's own, and refused where it has no effect.
    """
    fields = {f.name: f for f in dataclasses.fields(run_class(algorithm).config_class)}
    acting = {}
    for key, value in options.items():
        field = fields.get(key)
        regimes = None if field is None else field.metadata.get("regimes")
        if regimes is None or regime in regimes:
            acting[key] = value
    return acting


class _CuratorCheck:
    """Builds the curator of each distinct curriculum of a study once: its options are checked.

    A curator refuses bad options when it is built (the registry of
    :mod:`amaze.curriculum.curators`); the same options with another seed
    are as good, so each (curator, options, target, stages, branches, robot)
    is built once, not once per run.
    """

    def __init__(self, bad: Bad) -> None:
        self.bad = bad
        self.seen: set[str] = set()

    def __call__(self, run_id: str, config: Any) -> None:
        """Build the curator of ``config`` (a checked curriculum config) and its advisor, once."""
        if not getattr(config, "is_curriculum", False):
            return
        from amaze.curriculum.advice import check_advice, make_advisor
        from amaze.curriculum.curators import make_curator

        context = config.curator_context()
        advisor = getattr(config, "advisor", None)
        key = json.dumps(
            [config.curator, context.target, context.stages, context.branches, context.robot,
             dict(context.options), advisor, dict(getattr(config, "advisor_options", {}))],
            sort_keys=True, default=repr,
        )  # fmt: skip
        if key in self.seen:
            return
        try:
            curator = make_curator(config.curator, context)
        except (ValueError, TypeError) as problem:
            raise self.bad(f"run {run_id}: curator_options: {_problem(problem)}") from None
        if advisor is not None:
            try:
                make_advisor(advisor, config.advisor_context())
                check_advice(curator, config.curator, advisor)
            except (ValueError, TypeError) as problem:
                raise self.bad(f"run {run_id}: advisor: {_problem(problem)}") from None
        self.seen.add(key)


def _checked(run: PlannedRun, bad: Bad, curators: _CuratorCheck) -> PlannedRun:
    """``run`` with its config as its trainer's config class checks and completes it.

    A curriculum's curator is built too (``curators``), checking its options.
    """
    config_class = run_class(run.base_algorithm).config_class
    try:
        checked = config_class.from_dict(run.config).validate()
        if run.base_algorithm in EVOLUTION_ALGORITHMS:  # its options are checked when it starts
            from evolution.algorithms import algorithm_class

            algorithm_class(run.base_algorithm).config_class.from_dict(checked.algorithm)
    except (ValueError, TypeError) as problem:
        raise bad(f"run {run.id}: {_problem(problem)}") from None
    curators(run.id, checked)
    return PlannedRun(
        run.trainer, run.algorithm, run.budget, run.seed, checked.to_dict(), run.robot
    )

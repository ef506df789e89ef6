"""Evolution in the ``coevolution`` regime: agents and a maze population evolve together.

``amaze-evolve --regime coevolution --budget-seconds 300 --out runs/co`` runs
the generation loop (:class:`~evolution.generations.GenerationLoop`) with a
:class:`~amaze.curriculum.coevolution.MazePopulation` beside the agents::

    batch = mazes.propose()                     # replayed members + new mazes
    result = play(algorithm.ask(), batch)        # every agent, every maze, 4 rotations
    algorithm.tell(candidates, result.fitness)   # fitness: mean over the batch
    mazes.update(batch, per-maze results)        # scores, admission, retirement
    validate(the generation's best agent)        # on the validation mazes

**Champion.** Fitness on a changing batch does not compare across
generations, so the champion is chosen on fixed *validation mazes*:
``coevolution.validation`` (16) mazes of the target's family whose seeds are
neither the evaluation suite's nor any training maze's
(:func:`~amaze.curriculum.validation.validation_mazes`). Each generation's
best agent on its batch is played on them (4 rotations each); the champion
is the agent with the best validation fitness so far (the run's ``fitness``
measure, the earliest on ties). The suite itself is never looked at before
the end. ``summary.json`` also reports the champion on 32
other family mazes no part of the run played (``unseen_success_rate``,
``unseen_normalized_reward``; :func:`~amaze.curriculum.validation.unseen_mazes`).

**Budget.** Env steps count every episode played, validation included;
seconds everything the loop does. Where the time goes is reported in
``summary.json`` (``time``: evaluation, validation, breeding, mazes,
logging and checkpoints).

**Run folder**: the direct regime's (``config.json``, ``progress.csv``,
``checkpoints/state.npz``, ``agent.npz``, ``summary.json``) and

* ``mazes.csv``: every maze that was ever a member of the population (its
  string, origin, parent, birth, retirement, last scores and difficulty
  profile; :data:`~amaze.curriculum.coevolution.MAZES_CSV_FIELDS`), written
  with each checkpoint;
* ``population.png``: the members at the end, best score first, captioned
  with their score, success and difficulty;
* ``coevolution.png``: fitness on the batches, validation success of each
  generation's best and of the champion, and the difficulty of the batches
  and of the population against the target's, over env steps;
* ``trajectories/``: the champion in the target's 4 rotations.

**Backends.** With ``--backend ray`` the agents are played on Ray actors
(:mod:`evolution.backends`): each generation's batch of mazes is compiled
here and put in the object store once, and the actors read it at their
first part of that generation; the results, and so the run, are
bit-identical to the local backend's.

**Resume.** The checkpoint holds the algorithm, the maze population (its
members, records, scores and random generator) and the champion, so a run
resumed after a kill goes on bit-identically (seconds budgets aside).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from amaze.curriculum.coevolution import (
    MazePopulation,
    MazePopulationConfig,
    MazeResult,
    mazes_csv,
)
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.picture import save_population_png
from amaze.curriculum.validation import unseen_mazes, validation_mazes
from amaze.maze import rotations
from amaze.maze.render import save_picture
from amaze.runs.checkpoint import read_checkpoint, write_checkpoint
from amaze.runs.folder import ProgressLog, write_bytes
from evolution import EvolutionConfigError
from evolution.algorithms import SearchAlgorithm, make_algorithm
from evolution.backends import current_backend
from evolution.checkpoint import evolution_codec
from evolution.generations import ChosenAgent, GenerationLoop
from evolution.population import EvaluationBackend, PopulationEvaluator

__all__ = ["EvolutionCoevolutionRun", "save_coevolution_plot"]

PROGRESS_FIELDS = (
    "generation", "steps", "seconds", "best", "mean", "champion", "eval_seconds",
    "validation", "validation_success_rate", "champion_success_rate", "members", "admitted",
    "batch_difficulty", "population_difficulty", "diversity",
)  # fmt: skip
#: Version of the checkpoint layout; a checkpoint of another version is refused.
CHECKPOINT_VERSION = 1
#: Time categories of ``summary.json``'s ``time``.
TIME_PARTS = ("evaluation", "validation", "breeding", "mazes", "logging_and_checkpoints")


@dataclass
class _State:
    """The run state saved in every checkpoint."""

    algorithm: SearchAlgorithm
    mazes: MazePopulation
    generation: int = 0
    steps: int = 0
    validation_steps: int = 0
    seconds: float = 0.0
    eval_seconds: float = 0.0
    champion_fitness: float = -np.inf
    champion_success_rate: float = 0.0
    champion_generation: int = 0
    #: The champion: the best agent on the validation mazes so far.
    agent: ChosenAgent | None = None
    time: dict[str, float] = field(default_factory=lambda: dict.fromkeys(TIME_PARTS[:-1], 0.0))
    version: int = CHECKPOINT_VERSION
    #: The SHA-256 of the run's ``config.json`` (:attr:`~amaze.runs.lifecycle.Run.config_digest`).
    config_sha256: str | None = None


class EvolutionCoevolutionRun(GenerationLoop):
    """Generations of agents on batches of a co-evolving maze population."""

    progress_fields = PROGRESS_FIELDS
    outputs: ClassVar[tuple[str, ...]] = (
        "agent.npz", "summary.json", "progress.csv", "mazes.csv", "population.png",
        "coevolution.png",
    )  # fmt: skip
    state: _State  # type: ignore[assignment]
    regime_agent_rule = "best-validation"

    @cached_property
    def options(self) -> MazePopulationConfig:
        return MazePopulationConfig.from_dict(self.config.coevolution)

    @cached_property
    def validation_mazes(self) -> list[str]:
        c = self.config
        return validation_mazes(c.target, self.options.validation, c.seed)

    @cached_property
    def validation(self) -> EvaluationBackend:
        """The validation mazes in their rotations (the champion is chosen there)."""
        c = self.config
        return current_backend().evaluator(
            self.validation_mazes,
            c.robot,
            fitness=c.fitness,
            rotations=True,
            n_policies=self.options.validation_candidates,
        )

    # -- the lifecycle's hooks --------------------------------------------------------

    def start(self) -> None:
        c = self.config
        algorithm = make_algorithm(c.algo, c.algorithm, c.robot, c.seed)
        population = MazePopulation.for_run(c.target, self.options, c.seed, self.validation_mazes)
        self.state = _State(algorithm, population)
        self.validation  # noqa: B018
        self.check_budget()

    def generation_steps(self) -> tuple[int, str]:
        """The population on a batch's episodes (4 rotations each), at least a step each."""
        population = len(self.state.algorithm.ask())
        episodes = 4 * self.options.batch
        return population * episodes, f"{population} individuals on {episodes} episodes"

    def restore(self) -> int | None:
        if not self.checkpoint.exists():
            return None
        state = read_checkpoint(
            self.checkpoint, evolution_codec(_State), EvolutionConfigError, expected=_State
        )
        if state.version != CHECKPOINT_VERSION:
            raise EvolutionConfigError(
                f"checkpoint {str(self.checkpoint)!r} is of version {state.version!r},"
                f" not {CHECKPOINT_VERSION}"
            )
        self.check_config_digest(state.config_sha256, f"checkpoint {str(self.checkpoint)!r}")
        self.state = state
        self.validation  # noqa: B018
        return state.generation

    def figures(self) -> dict[str, Any]:
        c, s = self.config, self.state
        unseen = PopulationEvaluator(unseen_mazes(c.target, c.seed), c.robot, rotations=True)
        result = unseen.evaluate(self.final_agent())
        records = s.mazes.records
        return {
            "algo": c.algo,
            "robot": c.robot,
            "seed": c.seed,
            "regime": c.regime,
            "target": c.target,
            "fitness_measure": c.fitness,
            "champion_fitness": s.champion_fitness,
            "champion_validation_success_rate": s.champion_success_rate,
            "champion_generation": s.champion_generation,
            "unseen_success_rate": float(result.success_rate[0]),
            "unseen_normalized_reward": float(result.normalized_reward[0]),
            "generations": s.generation,
            "env_steps": s.steps,
            "validation_steps": s.validation_steps,
            "seconds": round(s.seconds, 3),
            "evaluation_seconds": round(s.eval_seconds, 3),
            "policy_steps_per_second": round(s.steps / max(s.eval_seconds, 1e-9)),
            "time": self.time_breakdown(),
            "mazes_ever": len(records),
            "members": len(s.mazes.members),
            "population_difficulty": s.mazes.mean_difficulty(),
            "target_difficulty": difficulty(c.target),
            "coevolution": self.options.to_dict(),
            "budget_steps": c.budget_steps,
            "budget_seconds": c.budget_seconds,
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The champion in the target's 4 rotations."""
        return [(f"target-rotation-{i}", m) for i, m in enumerate(rotations(self.config.target))]

    def extra_outputs(self) -> None:
        self.write_mazes_csv()
        s = self.state
        title = f"maze population after {s.generation} generations ({len(s.mazes.records)} ever)"
        save_population_png(s.mazes, self.out / "population.png", title)
        save_coevolution_plot(
            self.out / "progress.csv", self.out / "coevolution.png", self.config.target,
            title=f"{self.config.algo}, coevolution, seed {self.config.seed}",
        )  # fmt: skip

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        return (
            f"{summary['generations']} generations, {summary['mazes_ever']} mazes;"
            f" unseen family mazes: success {summary['unseen_success_rate']:.3f};"
            f" {super().headline(summary)}"
        )

    # -- one generation ---------------------------------------------------------------

    def generation(self) -> dict[str, Any]:
        """Play the population on a batch, breed, score the mazes, validate the best agents."""
        c, s = self.config, self.state
        clock = _Clock(s.time)
        algorithm = s.algorithm
        candidates = algorithm.ask()
        clock.lap("breeding")
        batch = s.mazes.propose()
        evaluator = current_backend().evaluator(
            [rotated for b in batch for rotated in s.mazes.generated(b.maze)],
            c.robot,
            fitness=c.fitness,
            n_policies=len(candidates),
        )
        clock.lap("mazes")
        policy = algorithm.population_policy(candidates)
        clock.lap("breeding")
        result = evaluator.evaluate(policy)
        clock.lap("evaluation")
        algorithm.tell(candidates, result.fitness)
        clock.lap("breeding")
        shape = (len(candidates), len(batch), 4)
        success = result.per_episode("success").reshape(shape)
        reward = result.per_episode("normalized_reward").reshape(shape)
        report = s.mazes.update(
            batch, [MazeResult.of(success[:, b], reward[:, b]) for b in range(len(batch))]
        )
        clock.lap("mazes")
        s.generation += 1
        validation = validation_success_rate = float("nan")
        champion = None
        options = self.options
        if (s.generation - 1) % options.validation_every == 0:
            top = np.argsort(-result.fitness, kind="stable")[: options.validation_candidates]
            checked = self.validation.evaluate(
                algorithm.population_policy([candidates[i] for i in top])
            )
            first = checked.best
            validation = float(checked.fitness[first])
            validation_success_rate = float(checked.success_rate[first])
            if validation > s.champion_fitness:
                s.champion_fitness, s.champion_success_rate = validation, validation_success_rate
                s.champion_generation = s.generation
                champion = algorithm.candidate_arrays(candidates[top[first]])
            s.steps += checked.env_steps
            s.validation_steps += checked.env_steps
            clock.lap("validation")
        s.steps += result.env_steps
        s.eval_seconds += result.seconds
        if champion is not None:
            self.keep_champion(*champion)
        diversity = s.mazes.diversity()
        clock.lap("mazes")
        s.seconds += clock.total
        return {
            "generation": s.generation,
            "steps": s.steps,
            "seconds": round(s.seconds, 3),
            "best": float(np.max(result.fitness)),
            "mean": float(np.mean(result.fitness)),
            "champion": s.champion_fitness,
            "eval_seconds": round(result.seconds, 4),
            "validation": validation,
            "validation_success_rate": validation_success_rate,
            "champion_success_rate": s.champion_success_rate,
            "members": len(s.mazes.members),
            "admitted": report.admitted,
            "batch_difficulty": round(report.batch_difficulty, 4),
            "population_difficulty": round(s.mazes.mean_difficulty(), 4),
            "diversity": round(diversity, 4),
        }

    def keep_champion(self, arrays: dict[str, np.ndarray], architecture: dict) -> None:
        """The generation's champion becomes the agent the run hands over."""
        s, c = self.state, self.config
        extra = {
            "regime": c.regime,
            "target": c.target,
            "validation_mazes": self.validation_mazes,
            "fitness": s.champion_fitness,
        }
        s.agent = ChosenAgent(
            {k: np.array(v) for k, v in arrays.items()},
            dict(architecture),
            s.champion_generation,
            s.steps,
            (s.champion_fitness,),
            extra,
        )

    def save_checkpoint(self) -> None:
        self.state.config_sha256 = self.config_digest
        write_checkpoint(self.checkpoint, self.state, evolution_codec(_State))
        self.write_mazes_csv()

    def time_breakdown(self) -> dict[str, float]:
        """Seconds spent per part of the loop; logging and checkpoints are the rest."""
        s = self.state
        parts = {k: s.time.get(k, 0.0) for k in TIME_PARTS[:-1]}
        parts["logging_and_checkpoints"] = max(s.seconds - sum(parts.values()), 0.0)
        return {k: round(v, 3) for k, v in parts.items()}

    def write_mazes_csv(self) -> Path:
        """``mazes.csv``: every maze that was ever a member, written atomically."""
        text = mazes_csv(self.state.mazes.records)
        return write_bytes(self.out / "mazes.csv", text.encode("utf-8"))


class _Clock:
    """Adds the time since its last lap to a category of ``parts``."""

    def __init__(self, parts: dict[str, float]) -> None:
        self.parts = parts
        self.started = self.last = time.perf_counter()

    def lap(self, part: str) -> None:
        now = time.perf_counter()
        self.parts[part] += now - self.last
        self.last = now

    @property
    def total(self) -> float:
        return self.last - self.started


def save_coevolution_plot(csv_path: Path, png_path: Path, target: str, title: str = "") -> Path:
    """``coevolution.png``: fitness, validation success and maze difficulty over env steps.

    Top: best and mean fitness of each generation on its batch. Middle: the
    validation success of each generation's best agent and of the champion.
    Bottom: the mean difficulty of each batch and of the population, and the
    target's as a dashed line.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = ProgressLog(csv_path, PROGRESS_FIELDS).rows()
    steps = np.array([float(r["steps"]) for r in rows])

    def column(name: str) -> list[float]:
        return [float(r[name]) for r in rows]

    figure, (fit, valid, hard) = plt.subplots(3, 1, figsize=(7, 8), dpi=110, sharex=True)
    fit.plot(steps, column("mean"), ":", label="mean on the batch")
    fit.plot(steps, column("best"), "-", lw=0.8, label="best on the batch")
    fit.set_ylabel("fitness")
    checked = np.array(column("validation_success_rate"))
    validated = ~np.isnan(checked)  # only every validation_every-th generation is validated
    valid.plot(steps[validated], checked[validated], "-", lw=0.6, alpha=0.6,
               label="generation's best")  # fmt: skip
    valid.plot(steps, column("champion_success_rate"), "-", lw=1.6, label="champion")
    valid.set_ylabel("validation success")
    valid.set_ylim(-0.02, 1.02)
    hard.plot(steps, column("batch_difficulty"), "-", lw=0.6, alpha=0.6, label="batch")
    hard.plot(steps, column("population_difficulty"), "-", lw=1.6, label="population")
    hard.axhline(difficulty(target), ls="--", color="grey", label="target")
    hard.set_ylabel("difficulty")
    hard.set_xlabel("environment steps")
    for axes in (fit, valid, hard):
        axes.grid(alpha=0.3)
        axes.legend(loc="lower right", fontsize=8)
    if title:
        fit.set_title(title)
    figure.tight_layout()
    try:
        save_picture(figure, png_path)
    finally:
        plt.close(figure)
    return png_path

"""Evolution runs: the generation loop, budgets, checkpoints and the evolution run folder.

:class:`EvolutionRun` is the evolution trainer of the shared run lifecycle
(:mod:`amaze.runs.lifecycle`: fresh start, resume, final report); this module
holds only what is evolution's own. :func:`evolve` drives any algorithm of
:data:`ALGORITHMS` (CMA-ES over a fixed network, the NEAT-like GA) through the
same loop::

    candidates = algorithm.ask()
    result = backend.evaluate(algorithm.population_policy(candidates))
    algorithm.tell(candidates, result.fitness)

The backend comes from :mod:`evolution.backends`: locally a
:class:`~evolution.population.PopulationEvaluator` on the batch engine, with
``--backend ray`` the population split across Ray actors (bit-identical
results). Fitness is the mean over the training mazes, each in its 4
rotations, of the paper's R̄ (or the success rate, or the reference's pretty
reward).

**Budgets**, as for the RL baselines: environment steps of the scored episodes
(:attr:`PopulationResult.env_steps`) and wall-clock seconds (everything the
loop does). A generation starts only if the steps left pay its least cost
(:meth:`EvolutionRun.generation_steps`) and seconds are left, before
``max_generations`` and while the algorithm goes on (CMA-ES has a restart left).

**Run folder** (``out``; ``docs/trainers/evolution.md`` lists it): ``progress.csv``
has a row per generation, ``generation, steps, seconds, best, mean, champion,
eval_seconds`` (the generation's best and mean fitness, the best fitness so
far, the seconds spent playing episodes). ``checkpoints/state.npz``, the whole
run state, is written atomically after the first generation, then after the
first generation that ends ``checkpoint_seconds`` (default 10; 0: every
generation) after the previous checkpoint, and after the last one, as JSON
plus arrays that name no function (:mod:`amaze.runs.checkpoint`,
:func:`evolution.checkpoint.evolution_codec`). ``agent.npz`` is the agent
``agent_rule`` picks, an agent file of :mod:`evolution.agent_file`.

**Resume.** :func:`resume` reloads the checkpoint and goes on, dropping the rows
of ``progress.csv`` written after it. The algorithms draw from their own
seeded generators, kept in the checkpoint, and evaluations are deterministic,
so a resumed run reaches the same champion and progress rows (seconds aside)
as an uninterrupted one, unless its *seconds* budget stops it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from amaze.maze import rotations
from amaze.maze.render import save_picture
from amaze.runs.checkpoint import read_checkpoint, write_checkpoint
from amaze.runs.config import RunConfig
from amaze.runs.folder import ProgressLog
from amaze.runs.lifecycle import Run, RunResult
from evolution import EvolutionConfigError
from evolution.algorithms import SearchAlgorithm, make_algorithm, population_size
from evolution.backends import current_backend
from evolution.checkpoint import evolution_codec
from evolution.config import EvolveConfig
from evolution.generations import ChosenAgent, GenerationLoop
from evolution.population import EvaluationBackend, PopulationResult, fewest_steps

__all__ = ["EvolutionRun", "EvolveConfig", "evolve", "resume"]

PROGRESS_FIELDS = ("generation", "steps", "seconds", "best", "mean", "champion", "eval_seconds")
#: Version of the checkpoint layout; a checkpoint of another version is refused.
CHECKPOINT_VERSION = 2


@dataclass
class _State:
    """The run state saved in every checkpoint."""

    algorithm: SearchAlgorithm
    generation: int = 0
    steps: int = 0
    seconds: float = 0.0
    eval_seconds: float = 0.0
    version: int = CHECKPOINT_VERSION
    #: The SHA-256 of the run's ``config.json`` (:attr:`~amaze.runs.lifecycle.Run.config_digest`).
    config_sha256: str | None = None
    #: The agent the run hands over, as ``agent_rule`` has picked it so far.
    agent: ChosenAgent | None = None
    #: Env steps of the evaluations on ``eval_mazes`` (``best-eval``), not part of the budget.
    evaluation_steps: int = 0


class EvolutionRun(GenerationLoop):
    """The evolution trainer: generations of ask, evaluate, tell until a budget is spent."""

    progress_fields = PROGRESS_FIELDS
    outputs = ("agent.npz", "summary.json", "progress.csv", "fitness.png")
    state: _State

    def __init__(self, out: str | os.PathLike, config: EvolveConfig) -> None:
        super().__init__(out, config)
        self.champion_fitness = -np.inf  # of the algorithm's champion, on the training mazes

    @cached_property
    def backend(self) -> EvaluationBackend:
        """Where populations are played: the training mazes in their rotations."""
        c = self.config
        return current_backend().evaluator(c.mazes, c.robot, fitness=c.fitness, rotations=True)

    # -- the lifecycle's hooks --------------------------------------------------

    @classmethod
    def run_class_for(cls, config: RunConfig) -> type[Run]:
        """This class for the direct regime, :class:`~evolution.curriculum.EvolutionCurriculumRun`
        for the curriculum ones, :class:`~evolution.coevolution.EvolutionCoevolutionRun`
        for coevolution, :class:`~evolution.edens_populations.EvolutionEdensPopulationsRun`
        for edens-populations."""
        if isinstance(config, EvolveConfig) and config.is_curriculum:
            from evolution.curriculum import EvolutionCurriculumRun

            return EvolutionCurriculumRun
        if isinstance(config, EvolveConfig) and config.regime == "coevolution":
            from evolution.coevolution import EvolutionCoevolutionRun

            return EvolutionCoevolutionRun
        if isinstance(config, EvolveConfig) and config.regime == "edens-populations":
            from evolution.edens_populations import EvolutionEdensPopulationsRun

            return EvolutionEdensPopulationsRun
        return cls

    def start(self) -> None:
        c = self.config
        self.state = _State(
            make_algorithm(c.algo, c.algorithm, c.robot, c.seed)
        )  # bad options fail here
        self.backend  # noqa: B018 (and bad mazes here, before anything is written)
        self.check_budget()

    def generation_steps(self) -> tuple[int, str]:
        """The population, each individual on the training mazes' rotations by shortest paths."""
        c = self.config
        population = population_size(self.state.algorithm)
        steps = population * fewest_steps(rotations(c.mazes), c.robot)
        return steps, f"{population} individuals on {4 * len(c.mazes)} episodes"

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
        self.backend  # noqa: B018
        champion = state.algorithm.champion
        if champion is not None:
            self.champion_fitness = float(champion[1])
        return state.generation

    def figures(self) -> dict[str, Any]:
        c, s = self.config, self.state
        return {
            "algo": c.algo,
            "robot": c.robot,
            "seed": c.seed,
            "mazes": list(c.mazes),
            "fitness_measure": c.fitness,
            "champion_fitness": self.champion_fitness,
            "generations": s.generation,
            "env_steps": s.steps,
            "seconds": round(s.seconds, 3),
            "evaluation_seconds": round(s.eval_seconds, 3),
            "policy_steps_per_second": round(s.steps / max(s.eval_seconds, 1e-9)),
            "budget_steps": c.budget_steps,
            "budget_seconds": c.budget_seconds,
            "eval_mazes": list(c.eval_mazes or []),
            "evaluation_steps": s.evaluation_steps,
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The agent in the 4 rotations of the first training maze."""
        mazes = rotations(self.config.mazes[0])
        return [(f"training-rotation-{index}", maze) for index, maze in enumerate(mazes)]

    def extra_outputs(self) -> None:
        plot_progress(self.out / "progress.csv", self.out / "fitness.png", self.config)

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        return (
            f"{summary['generations']} generations,"
            f" {summary['policy_steps_per_second'] / 1e6:.2f} M policy-steps/s;"
            f" champion fitness {summary['champion_fitness']:.3f}"
            f" ({summary.get('fitness_measure', 'normalized_reward')});"
            f" {super().headline(summary)}"
        )

    # -- evolution's own ----------------------------------------------------------

    def generation(self) -> dict[str, Any]:
        """Evaluate and breed one generation; return its progress row."""
        started = time.perf_counter()
        algorithm = self.state.algorithm
        candidates = algorithm.ask()
        result = self.backend.evaluate(algorithm.population_policy(candidates))
        algorithm.tell(candidates, result.fitness)
        s = self.state
        s.generation += 1
        s.steps += result.env_steps
        s.eval_seconds += result.seconds
        champion = algorithm.champion
        if champion is not None and champion[1] > self.champion_fitness:
            self.champion_fitness = float(champion[1])
        self.choose_agent(candidates, result)
        s.seconds += time.perf_counter() - started
        return {
            "generation": s.generation,
            "steps": s.steps,
            "seconds": round(s.seconds, 3),
            "best": float(np.max(result.fitness)),
            "mean": float(np.mean(result.fitness)),
            "champion": self.champion_fitness,
            "eval_seconds": round(result.seconds, 4),
        }

    def choose_agent(self, candidates: list[Any], result: PopulationResult) -> None:
        """The generation's part in choosing the agent, by ``agent_rule``.

        ``best-fitness``: the algorithm's champion when it improves; ``final``:
        every generation's best; ``best-eval``: the generation's best played on
        the evaluation mazes, kept when it beats the one kept (success rate,
        then R̄; the earlier on ties).
        """
        c, s = self.config, self.state
        algorithm = s.algorithm
        if c.agent_rule == "best-fitness":
            if s.agent is not None and s.agent.score[0] >= self.champion_fitness:
                return
            arrays, architecture = algorithm.champion_arrays()
            score: tuple[float, ...] = (self.champion_fitness,)
        else:
            best = candidates[result.best]
            arrays, architecture = algorithm.candidate_arrays(best)
            score = (float(result.fitness[result.best]),)
            if c.agent_rule == "best-eval":
                played = self.evaluation.evaluate(algorithm.population_policy([best]))
                s.evaluation_steps += played.env_steps
                score = (float(played.success_rate[0]), float(played.normalized_reward[0]))
                if s.agent is not None and s.agent.score >= score:
                    return
        extra = {"mazes": list(c.mazes), "fitness": float(result.fitness[result.best])}
        if c.agent_rule == "best-fitness":
            extra["fitness"] = self.champion_fitness
        s.agent = ChosenAgent(
            {k: np.array(v) for k, v in arrays.items()},
            dict(architecture),
            s.generation,
            s.steps,
            score,
            extra,
        )

    @cached_property
    def evaluation(self) -> EvaluationBackend:
        """The evaluation mazes in their rotations (``agent_rule`` ``best-eval``)."""
        c = self.config
        return current_backend().evaluator(c.eval_mazes, c.robot, fitness=c.fitness, rotations=True)

    def save_checkpoint(self) -> None:
        self.state.config_sha256 = self.config_digest
        write_checkpoint(self.checkpoint, self.state, evolution_codec(_State))


def plot_progress(csv_path: Path, png_path: Path, config: EvolveConfig) -> None:
    """Best, mean and champion fitness of every generation against env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = ProgressLog(csv_path, PROGRESS_FIELDS).rows()
    steps = np.array([int(r["steps"]) for r in rows], dtype=float)
    figure, axes = plt.subplots(figsize=(7, 4), dpi=110)
    for key, style in (("mean", ":"), ("best", "-"), ("champion", "--")):
        axes.plot(steps, [float(r[key]) for r in rows], style, label=key)
    axes.set_xlabel("environment steps")
    axes.set_ylabel(f"fitness ({config.fitness})")
    axes.set_title(f"{config.algo} on {config.robot}, seed {config.seed}")
    axes.grid(alpha=0.3)
    axes.legend(loc="lower right")
    figure.tight_layout()
    try:
        save_picture(figure, png_path)
    finally:
        plt.close(figure)


def evolve(
    config: EvolveConfig | Mapping[str, Any], out: str | os.PathLike, *, progress: str = "off"
) -> RunResult:
    """Run a fresh evolution as ``config`` says and write the run folder ``out``.

    Args:
        config: the run's config (the keys of ``amaze-evolve``'s ``config.json``).
        out: the run folder to create (new or empty).
        progress: ``bar``, ``lines`` or ``off``.

    Returns:
        The run's result (its folder, summary, headline and outputs)."""
    return EvolutionRun.fresh(config, out, progress=progress)


def resume(out: str | os.PathLike, *, progress: str = "off") -> RunResult:
    """Continue the run in ``out`` from its latest checkpoint (same config, same seed)."""
    return EvolutionRun.resume(out, progress=progress)

"""Evolution runs: the generation loop, budgets, run folders, checkpoints and resume.

:func:`evolve` drives any algorithm of :data:`ALGORITHMS` (CMA-ES over a fixed
network, the NEAT-like GA) through the same loop::

    candidates = algorithm.ask()
    result = backend.evaluate(algorithm.population_policy(candidates))
    algorithm.tell(candidates, result.fitness)

The backend is an :class:`~evolution.population.EvaluationBackend` (locally a
:class:`~evolution.population.PopulationEvaluator` on the batch engine; a
distributed one can replace it without touching the algorithms). Fitness is
the mean over the training mazes, each in its 4 rotations, of the paper's R̄
(or the success rate, or the reference's pretty reward).

**Budgets** are counted as for the RL baselines: environment steps (the
steps of the scored episodes, :attr:`PopulationResult.env_steps`) and
wall-clock seconds (everything the loop does: evaluation, breeding, logging
and checkpoints). A run stops after the first generation that reaches
either budget (so it may overshoot by less than one generation), after
``max_generations``, or when the algorithm has stopped (CMA-ES with no
restart left).

**Run folder** (``out``):

* ``config.json``: the :class:`EvolveConfig`;
* ``progress.csv``: one row per generation: ``generation, steps, seconds,
  best, mean, champion, eval_seconds`` (best and mean fitness of the
  generation, the best fitness so far, the seconds spent playing episodes);
* ``checkpoints/state.pkl``: the whole run state after a generation (the
  algorithm with its random generators, steps and seconds spent), written
  atomically after the first generation, then after the first generation that
  ends ``checkpoint_seconds`` (default 10) after the previous checkpoint, and
  after the last one (``checkpoint_seconds: 0``: after every generation). A
  checkpoint of a CMA-ES run with a large population weighs megabytes, and
  fast generations take milliseconds: writing one every generation would
  cost more than the evolution. It is a pickle: load only checkpoints you
  wrote yourself;
* ``champion.npz``: the best individual so far, an agent file of
  :mod:`evolution.agent_file` (no pickle; ``amaze run --controller champion.npz``);
* ``summary.json``: the champion on the standard evaluation suite
  (``success_rate``, ``normalized_reward``, ``input_recognition``...), its
  training fitness and the budget spent (``env_steps``, ``seconds``,
  ``generations``, ``policy_steps_per_second``);
* ``fitness.png``: best, mean and champion fitness against env steps;
* ``trajectories/``: the champion in the 4 rotations of the first training maze.

**Resume.** :func:`resume` reloads the checkpoint and goes on. Every draw of
the algorithms comes from their own seeded generators, kept in the
checkpoint, and evaluations are deterministic, so a run resumed after a kill
reaches the same champion and the same progress rows (seconds aside) as an
uninterrupted one. A run stopped by its *seconds* budget is the exception:
where it stops depends on the machine's speed.
"""

from __future__ import annotations

import json
import os
import pickle
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.robot import as_robot
from amaze.agents.trajectories import save_trajectory_png
from amaze.evaluation.policy import record_episode
from amaze.evaluation.protocol import Evaluator
from amaze.evaluation.suite import PAPER_TRAINING_MAZE, rotations
from amaze.runs.folder import ProgressLog, config_from_dict, write_bytes, write_json
from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, save_agent
from evolution.population import FITNESS, EvaluationBackend, PopulationEvaluator

__all__ = ["ALGORITHMS", "EvolveConfig", "EvolveResult", "evolve", "resume"]

ALGORITHMS = ("cmaes", "neat")
PROGRESS_FIELDS = ("generation", "steps", "seconds", "best", "mean", "champion", "eval_seconds")
#: Version of the checkpoint layout; a checkpoint of another version is refused.
CHECKPOINT_VERSION = 1


@dataclass
class EvolveConfig:
    """Everything that defines an evolution run (stored as ``config.json``).

    ``algorithm`` holds the algorithm's own options (:class:`~evolution.cmaes.CMAESConfig`
    or :class:`~evolution.neat.NeatConfig` fields); ``budget_steps`` and
    ``budget_seconds`` may each be ``None`` (no limit), not both.
    """

    algo: str = "cmaes"
    robot: str = "DD"
    mazes: list[str] = field(default_factory=lambda: [PAPER_TRAINING_MAZE])
    fitness: str = "paper_reward"
    budget_steps: int | None = 3_000_000
    budget_seconds: float | None = None
    max_generations: int | None = None
    seed: int = 0
    checkpoint_seconds: float = 10.0
    algorithm: dict[str, Any] = field(default_factory=dict)

    def validate(self) -> EvolveConfig:
        """Check every field; raise :class:`EvolutionConfigError` naming the bad value."""
        if self.algo not in ALGORITHMS:
            raise EvolutionConfigError(
                f"unknown algorithm {self.algo!r} (choose from {', '.join(ALGORITHMS)})"
            )
        try:
            self.robot = as_robot(self.robot).to_string()
        except ValueError as error:
            raise EvolutionConfigError(f"robot {self.robot!r}: {error}") from None
        if isinstance(self.mazes, str):
            self.mazes = [m for m in self.mazes.split(",") if m]
        if not isinstance(self.mazes, list) or not self.mazes:
            raise EvolutionConfigError(f"mazes {self.mazes!r} is not a non-empty list of strings")
        if self.fitness not in FITNESS:
            raise EvolutionConfigError(
                f"fitness {self.fitness!r} is not one of {', '.join(FITNESS)}"
            )
        for name in ("budget_steps", "max_generations"):
            value = getattr(self, name)
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, int) or value < 1
            ):
                raise EvolutionConfigError(f"{name} {value!r} is not a positive integer")
        seconds = self.budget_seconds
        if seconds is not None and (
            isinstance(seconds, bool) or not isinstance(seconds, int | float) or not seconds > 0
        ):
            raise EvolutionConfigError(f"budget_seconds {seconds!r} is not a positive number")
        if self.budget_steps is None and seconds is None and self.max_generations is None:
            raise EvolutionConfigError("a run needs a budget: budget_steps or budget_seconds")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise EvolutionConfigError(f"seed {self.seed!r} is not a non-negative integer")
        every = self.checkpoint_seconds
        if isinstance(every, bool) or not isinstance(every, int | float) or not every >= 0:
            raise EvolutionConfigError(f"checkpoint_seconds {every!r} is not a number >= 0")
        if not isinstance(self.algorithm, dict):
            raise EvolutionConfigError(f"algorithm {self.algorithm!r} is not a JSON object")
        return self

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EvolveConfig:
        """A config from a JSON object; unknown keys are errors."""
        return config_from_dict(cls, data, EvolutionConfigError).validate()

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class EvolveResult:
    """What :func:`evolve` returns: the champion (a policy) and the run's figures."""

    champion: Any
    fitness: float
    generations: int
    env_steps: int
    seconds: float
    summary: dict[str, Any]


def make_algorithm(config: EvolveConfig) -> Any:
    """A fresh algorithm object as ``config`` says (options checked by the algorithm)."""
    if config.algo == "cmaes":
        from evolution.cmaes import CMAESAlgorithm, CMAESConfig

        return CMAESAlgorithm(CMAESConfig.from_dict(config.algorithm), config.robot, config.seed)
    from evolution.neat import NeatAlgorithm, NeatConfig

    return NeatAlgorithm(NeatConfig.from_dict(config.algorithm), config.robot, config.seed)


@dataclass
class _State:
    """The run state saved in every checkpoint."""

    algorithm: Any
    generation: int = 0
    steps: int = 0
    seconds: float = 0.0
    eval_seconds: float = 0.0
    version: int = CHECKPOINT_VERSION


class _Run:
    """One run folder and the loop that fills it."""

    def __init__(self, out: Path, config: EvolveConfig, state: _State) -> None:
        self.out = out
        self.config = config
        self.state = state
        self.progress = ProgressLog(out / "progress.csv", PROGRESS_FIELDS)
        self.checkpoint = out / "checkpoints" / "state.pkl"
        self.backend: EvaluationBackend = PopulationEvaluator(
            config.mazes, config.robot, fitness=config.fitness, rotations=True
        )
        self.champion_fitness = -np.inf
        champion = getattr(state.algorithm, "champion", None)
        if champion is not None:
            self.champion_fitness = float(champion[1])

    def budget_left(self) -> bool:
        c, s = self.config, self.state
        if c.budget_steps is not None and s.steps >= c.budget_steps:
            return False
        if c.budget_seconds is not None and s.seconds >= c.budget_seconds:
            return False
        if c.max_generations is not None and s.generation >= c.max_generations:
            return False
        return not getattr(s.algorithm, "stopped", False)

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
        s.seconds += time.perf_counter() - started
        champion = algorithm.champion
        if champion is not None and champion[1] > self.champion_fitness:
            self.champion_fitness = float(champion[1])
            self.save_champion()
        return {
            "generation": s.generation,
            "steps": s.steps,
            "seconds": round(s.seconds, 3),
            "best": float(np.max(result.fitness)),
            "mean": float(np.mean(result.fitness)),
            "champion": self.champion_fitness,
            "eval_seconds": round(result.seconds, 4),
        }

    def save_champion(self) -> None:
        arrays, architecture = self.state.algorithm.champion_arrays()
        save_agent(
            self.out / "champion.npz",
            arrays,
            {
                "architecture": architecture,
                "robot": self.config.robot,
                "mazes": list(self.config.mazes),
                "fitness": self.champion_fitness,
                "fitness_measure": self.config.fitness,
                "algorithm": self.config.algo,
                "generation": self.state.generation,
                "seed": self.config.seed,
            },
        )

    def save_checkpoint(self) -> None:
        write_bytes(self.checkpoint, pickle.dumps(self.state, protocol=pickle.HIGHEST_PROTOCOL))

    def _done(self) -> float:
        """How much of the budget the progress bar counts is spent (steps, else seconds)."""
        if self.config.budget_steps is not None:
            return min(self.state.steps, self.config.budget_steps)
        if self.config.budget_seconds is not None:
            return min(self.state.seconds, self.config.budget_seconds)
        return self.state.generation

    def loop(self, progress_bar: bool) -> None:
        """Generations until a budget is spent, with a progress bar (ETA from the budget)."""
        from tqdm import tqdm

        c = self.config
        if c.budget_steps is not None:
            total, unit = c.budget_steps, "steps"
        elif c.budget_seconds is not None:
            total, unit = c.budget_seconds, "s"
        else:
            total, unit = c.max_generations, "gen"
        with tqdm(
            total=total,
            initial=self._done(),
            unit=unit,
            unit_scale=True,
            disable=not progress_bar,
            desc=f"{c.algo} seed {c.seed}",
            dynamic_ncols=True,
        ) as bar:
            last_checkpoint: float | None = None
            while self.budget_left():
                row = self.generation()
                logging_started = time.perf_counter()
                self.progress.append(row)
                due = last_checkpoint is None or (
                    self.state.seconds - last_checkpoint >= c.checkpoint_seconds
                )
                if due or not self.budget_left():
                    self.save_checkpoint()
                    last_checkpoint = self.state.seconds
                self.state.seconds += time.perf_counter() - logging_started
                rate = self.state.steps / max(self.state.eval_seconds, 1e-9)
                bar.set_postfix(
                    gen=row["generation"],
                    best=f"{row['best']:.3f}",
                    mean=f"{row['mean']:.3f}",
                    champion=f"{row['champion']:.3f}",
                    steps_s=f"{rate / 1e6:.2f}M",
                    refresh=False,
                )
                bar.update(self._done() - bar.n)

    def finish(self) -> EvolveResult:
        """Evaluate the champion on the standard suite; write summary, plot and trajectories."""
        if not (self.out / "champion.npz").exists():
            raise EvolutionConfigError("the run evaluated no generation (budget too small?)")
        champion = load_agent(self.out / "champion.npz")
        summary = Evaluator(self.config.robot).evaluate(champion).summary()
        s = self.state
        summary.update(
            {
                "algo": self.config.algo,
                "robot": self.config.robot,
                "seed": self.config.seed,
                "mazes": list(self.config.mazes),
                "fitness_measure": self.config.fitness,
                "champion_fitness": self.champion_fitness,
                "generations": s.generation,
                "env_steps": s.steps,
                "seconds": round(s.seconds, 3),
                "evaluation_seconds": round(s.eval_seconds, 3),
                "policy_steps_per_second": round(s.steps / max(s.eval_seconds, 1e-9)),
                "budget_steps": self.config.budget_steps,
                "budget_seconds": self.config.budget_seconds,
            }
        )
        write_json(self.out / "summary.json", summary)
        plot_progress(self.out / "progress.csv", self.out / "fitness.png", self.config)
        for index, maze in enumerate(rotations(self.config.mazes[0])):
            _, trajectory = record_episode(maze, self.config.robot, champion)
            save_trajectory_png(
                maze,
                trajectory,
                self.out / "trajectories" / f"training-rotation-{index}.png",
                robot=self.config.robot,
                caption=True,
            )
        return EvolveResult(
            champion, self.champion_fitness, s.generation, s.steps, s.seconds, summary
        )


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
    png_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = png_path.with_name(f".{png_path.name}.tmp.png")
    figure.savefig(tmp)
    plt.close(figure)
    os.replace(tmp, png_path)


def evolve(
    config: EvolveConfig | dict[str, Any], out: str | os.PathLike, *, progress_bar: bool = False
) -> EvolveResult:
    """Run a fresh evolution as ``config`` says and write the run folder ``out``."""
    if isinstance(config, dict):
        config = EvolveConfig.from_dict(config)
    config.validate()
    path = Path(out)
    if (path / "config.json").exists():
        raise EvolutionConfigError(f"{str(path)!r} already holds a run (use resume)")
    algorithm = make_algorithm(config)  # bad algorithm options fail before anything is written
    run = _Run(path, config, _State(algorithm))  # and bad mazes here
    path.mkdir(parents=True, exist_ok=True)
    write_json(path / "config.json", config.to_dict())
    run.loop(progress_bar)
    return run.finish()


def resume(out: str | os.PathLike, *, progress_bar: bool = False) -> EvolveResult:
    """Continue the run in ``out`` from its latest checkpoint (same config, same seed)."""
    path = Path(out)
    config_path = path / "config.json"
    if not config_path.exists():
        raise EvolutionConfigError(f"{str(path)!r} holds no run (no config.json)")
    try:
        config = EvolveConfig.from_dict(json.loads(config_path.read_text()))
    except json.JSONDecodeError as error:
        raise EvolutionConfigError(f"{str(config_path)!r} is not JSON: {error}") from None
    checkpoint = path / "checkpoints" / "state.pkl"
    if checkpoint.exists():
        state = pickle.loads(checkpoint.read_bytes())
        if not isinstance(state, _State) or state.version != CHECKPOINT_VERSION:
            raise EvolutionConfigError(f"{str(checkpoint)!r} is not a checkpoint of this version")
        run = _Run(path, config, state)
        run.progress.keep(lambda row: int(row["generation"]) <= state.generation)
        if state.generation and not (path / "champion.npz").exists():
            run.save_champion()
    else:
        run = _Run(path, config, _State(make_algorithm(config)))
        run.progress.keep(lambda row: False)
    run.loop(progress_bar)
    return run.finish()

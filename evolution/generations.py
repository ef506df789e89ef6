"""The generation loop of the direct regime, and the agent every evolution run hands over.

:class:`GenerationLoop` is a :class:`~amaze.runs.lifecycle.Run` whose
training is ``generation()`` after ``generation()`` until a budget is spent
(env steps, wall-clock seconds, generations, or the algorithm stopping),
with a progress bar, a ``progress.csv`` row per generation and a checkpoint
every ``checkpoint_seconds`` of run time and after the last generation. The
direct regime (:class:`evolution.run.EvolutionRun`) supplies the generation
and the checkpoint; each generation updates the state's :class:`ChosenAgent`,
the agent the run hands over as its rule picks it (written at the end as
``agent.npz``). The coevolution regime
(:class:`evolution.coevolution.EvolutionCoevolutionRun`) plays the shared
co-evolution loop instead, and hands its champion over the same way
(:func:`chosen_policy`, :func:`save_chosen`, :func:`search_stop_reason`).
"""

from __future__ import annotations

import os
import time
from abc import abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from amaze.runs.anytime import Spent
from amaze.runs.lifecycle import Run
from amaze.runs.progress import Progress
from evolution.agent_file import policy_from_agent_arrays, save_agent
from evolution.config import EvolveConfig

__all__ = ["ChosenAgent", "GenerationLoop", "chosen_policy", "save_chosen", "search_stop_reason"]


@dataclass
class ChosenAgent:
    """The agent a run hands over, as its rule has picked it so far (part of the state)."""

    arrays: dict[str, np.ndarray]
    architecture: dict[str, Any]
    #: The generation it was found in (1: the initial population, before any update).
    generation: int
    #: The run's env steps at the end of that generation.
    steps: int
    #: What the rule ranks agents by (higher is better; ties keep the earlier one).
    score: tuple[float, ...] = ()
    #: Figures for the agent file's metadata (its fitness...).
    extra: dict[str, Any] = field(default_factory=dict)


class GenerationLoop(Run):
    """Generations until a budget is spent; subclasses play one generation and save state.

    ``self.state`` must have ``algorithm`` (with ``stopped``), ``generation``,
    ``steps``, ``seconds``, ``eval_seconds`` and ``agent`` (a :class:`ChosenAgent`
    or ``None`` before the first generation).
    """

    agent_file = "agent.npz"
    #: The rule that picks the agent (:meth:`agent_figures`), when the config has none.
    regime_agent_rule = ""

    config_class = EvolveConfig
    position_field = "generation"
    checkpoint_files = ("state.npz",)
    config: EvolveConfig

    def __init__(self, out: str | os.PathLike, config: EvolveConfig) -> None:
        super().__init__(out, config)
        self.checkpoint = self.checkpoints / self.checkpoint_files[0]
        self.state: Any  # set by start() or restore()

    @abstractmethod
    def generation(self) -> dict[str, Any]:
        """Play and breed one generation; return its ``progress.csv`` row."""

    @abstractmethod
    def save_checkpoint(self) -> None:
        """Write the state to :attr:`checkpoint`, atomically."""

    @abstractmethod
    def generation_steps(self) -> tuple[int, str]:
        """The fewest env steps the next generation can spend, and what it is.

        A generation starts only if the steps budget left pays it (it may then
        spend more, by less than a generation); a fresh run whose budget
        cannot pay the first one is refused before its folder is written.
        """

    def check_budget(self) -> None:
        """Refuse a steps budget that cannot pay the first generation (:meth:`generation_steps`)."""
        c = self.config
        steps, what = self.generation_steps()
        if c.budget_steps is not None and c.budget_steps < steps:
            raise c.error(
                f"budget_steps {c.budget_steps} cannot pay one generation: {what} spend at"
                f" least {steps} steps"
            )

    def train(self, progress: str) -> None:
        """Generations until a budget is spent, showing ``progress`` (ETA from the budget)."""
        c = self.config
        if c.budget_steps is not None:
            total, unit = c.budget_steps, "steps"
        elif c.budget_seconds is not None:
            total, unit = c.budget_seconds, "s"
        else:
            total, unit = c.max_generations, "generations"
        desc = f"{c.algo} {c.regime} seed {c.seed}"
        with Progress(total, unit, desc, mode=progress, initial=self._done()) as shown:
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
                self.evaluate_anytime()  # outside the seconds the budget counts
                rate = self.state.steps / max(self.state.eval_seconds, 1e-9)
                shown.update(
                    self._done(),
                    generation=row["generation"],
                    best=f"{row['best']:.3f}",
                    champion=f"{row['champion']:.3f}",
                    steps_s=f"{rate / 1e6:.2f}M",
                )

    def spent(self) -> Spent:
        s = self.state
        return Spent(s.generation, s.steps, s.seconds, generations=s.generation)

    def final_agent(self) -> Any:
        return chosen_policy(self.state.agent, self.config)

    def save_agent(self, agent: Any, path: Path) -> None:
        save_chosen(self.state.agent, self.config, path)

    def agent_figures(self) -> dict[str, Any]:
        chosen = self.state.agent
        return {
            "agent_rule": self.config.agent_rule or self.regime_agent_rule,
            "agent_steps": chosen.steps,
            "agent_generation": chosen.generation,
            "agent_untrained": chosen.generation == 1,
        }

    def stop_reason(self) -> str:
        c, s = self.config, self.state
        reason = search_stop_reason(s.algorithm, c, s.generation)
        if not reason and c.budget_steps is not None:
            least, what = self.generation_steps()
            if c.budget_steps - s.steps < least:
                reason = (
                    f"the {c.budget_steps - s.steps:,} steps left cannot pay another generation"
                    f" ({what} spend at least {least:,})"
                )
        return reason

    def budget_left(self) -> bool:
        """Whether another generation starts: every budget has room, the algorithm goes on."""
        c, s = self.config, self.state
        if s.algorithm.stopped:
            return False
        if c.budget_steps is not None and c.budget_steps - s.steps < self.generation_steps()[0]:
            return False
        if c.budget_seconds is not None and s.seconds >= c.budget_seconds:
            return False
        return c.max_generations is None or s.generation < c.max_generations

    def _done(self) -> float:
        """How much of the budget the progress bar counts is spent (steps, else seconds)."""
        if self.config.budget_steps is not None:
            return min(self.state.steps, self.config.budget_steps)
        if self.config.budget_seconds is not None:
            return min(self.state.seconds, self.config.budget_seconds)
        return self.state.generation


def chosen_policy(chosen: ChosenAgent | None, config: EvolveConfig) -> Any:
    """The policy of the agent a run hands over; the config's error while there is none."""
    if chosen is None:
        raise config.error("the run evaluated no generation")
    metadata = {"architecture": chosen.architecture, "robot": config.robot}
    return policy_from_agent_arrays(chosen.arrays, metadata, where=f"the {config.algo} agent")


def save_chosen(chosen: ChosenAgent, config: EvolveConfig, path: Path) -> None:
    """Write the agent a run hands over to ``path``, an agent file with the run's metadata."""
    metadata = {
        "architecture": chosen.architecture,
        "robot": config.robot,
        "algorithm": config.algo,
        "fitness_measure": config.fitness,
        "generation": chosen.generation,
        "seed": config.seed,
        **chosen.extra,
    }
    save_agent(path, chosen.arrays, metadata)


def search_stop_reason(algorithm: Any, config: EvolveConfig, generation: int) -> str:
    """Why the search ends besides a budget: the algorithm stopped, or ``max_generations``."""
    if algorithm.stopped:
        reasons = ", ".join(sorted(getattr(algorithm, "stop_reasons", {}))) or "its criteria"
        return f"the {config.algo} search stopped, with no restart left ({reasons})"
    if config.max_generations is not None and generation >= config.max_generations:
        return f"max_generations {config.max_generations} reached"
    return ""

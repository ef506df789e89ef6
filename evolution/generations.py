"""The generation loop that every evolution regime without stages shares.

:class:`GenerationLoop` is a :class:`~amaze.runs.lifecycle.Run` whose
training is ``generation()`` after ``generation()`` until a budget is spent
(env steps, wall-clock seconds, generations, or the algorithm stopping),
with a progress bar, a ``progress.csv`` row per generation and a checkpoint
every ``checkpoint_seconds`` of run time and after the last generation. The
direct regime (:class:`evolution.run.EvolutionRun`) and the coevolution
regime (:class:`evolution.coevolution.EvolutionCoevolutionRun`) supply the
generation, the checkpoint and the champion.
"""

from __future__ import annotations

import os
import time
from abc import abstractmethod
from typing import Any

from amaze.runs.lifecycle import Run
from evolution.config import EvolveConfig

__all__ = ["GenerationLoop"]


class GenerationLoop(Run):
    """Generations until a budget is spent; subclasses play one generation and save state.

    ``self.state`` must have ``algorithm`` (with ``stopped``), ``generation``,
    ``steps``, ``seconds`` and ``eval_seconds``.
    """

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
    def save_champion(self) -> None:
        """Write ``champion.npz`` from the state."""

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

    def train(self, progress_bar: bool) -> None:
        """Generations until a budget is spent, with a progress bar (ETA from the budget)."""
        from tqdm import tqdm

        c = self.config
        if self.state.generation and not (self.out / "champion.npz").exists():
            self.save_champion()  # a champion lost after the checkpoint is written again
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

"""Evolution in the curriculum regimes: the EDHuCAT loop with an evolution learner.

``amaze-evolve --regime edhucat --curator random --stages 3 --branches 2
--budget-steps 600000 --out runs/e`` (or ``--regime interpolation``) runs the
curriculum loop of :class:`amaze.runs.curriculum.CurriculumRun` with an
:class:`~evolution.learner.EvolutionLearner` (the config's ``algo``,
``algorithm`` options, ``fitness`` and ``checkpoint_seconds``):
:meth:`evolution.run.EvolutionRun.run_class_for` hands a curriculum config to
:class:`EvolutionCurriculumRun`. Each branch folder's ``agent/`` holds the
learner (``learner.npz``) and its champion (``champion.npz``, an agent file
for ``amaze run --controller``); ``checkpoint/`` holds the learner mid-session
while the branch trains. Evolution is deterministic, so ``--replay`` of a run
and ``--resume`` of a killed one reach its final champion bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

from amaze.maze import rotations
from amaze.runs.curriculum import CurriculumRun
from amaze.runs.folder import write_bytes
from evolution.algorithms import make_algorithm
from evolution.config import EvolveConfig
from evolution.learner import EvolutionLearner, load_learner
from evolution.population import fewest_steps

__all__ = ["EvolutionCurriculumRun"]


class EvolutionCurriculumRun(CurriculumRun):
    """The curriculum loop whose learner is an :class:`~evolution.learner.EvolutionLearner`."""

    config_class = EvolveConfig
    config: EvolveConfig
    agent_file = "agent.npz"
    outputs: ClassVar[tuple[str, ...]] = ("agent.npz", *CurriculumRun.outputs)

    def start(self) -> None:
        """Bad algorithm options fail here, before anything is written; then the curator."""
        self._population  # noqa: B018 (builds the algorithm once)
        super().start()

    @cached_property
    def _population(self) -> int:
        """Individuals of the algorithm's first generation (bad options fail here)."""
        c = self.config
        return len(make_algorithm(c.algo, c.algorithm, c.robot, c.seed).ask())

    def smallest_unit(self) -> tuple[int, str]:
        """A generation of the first population on the trivial maze's 4 rotations, at least."""
        c = self.config
        trivial = rotations(c.curator_context().trivial_maze())
        steps = self._population * fewest_steps(trivial, c.robot)
        return steps, f"a generation of {self._population} individuals on the trivial maze"

    def new_learner(self, seed: int) -> EvolutionLearner:
        c = self.config
        return EvolutionLearner.new(
            c.algo,
            c.algorithm,
            c.robot,
            seed,
            fitness=c.fitness,
            checkpoint_seconds=c.checkpoint_seconds,
        )

    def load_learner(self, folder: Path) -> EvolutionLearner:
        return load_learner(folder)

    def save_agent(self, agent: Any, path: Path) -> None:
        """The final learner's champion, as its branch's ``agent/champion.npz`` holds it."""
        write_bytes(path, (self._final_folder() / "agent" / "champion.npz").read_bytes())

    def learner_figures(self) -> dict[str, Any]:
        """The algorithm and fitness measure, the final learner's and the run's generations.

        ``generations`` and ``policy_steps_per_second`` are over every branch
        of the run; ``lineage_generations`` over the final agent's lineage;
        ``champion_fitness`` is the final champion's on its last mazes.
        """
        c = self.config
        generations, steps, seconds = 0, 0, 0.0
        folders = [self._branch_folder(k) for record in self.records for k in record.candidates]
        if self.finishing is not None:
            folders.append(self._final_folder())
        for folder in folders:
            session = load_learner(folder / "agent").last_session
            if session is not None:
                generations += session.generations
                steps += session.steps
                seconds += session.eval_seconds
        figures: dict[str, Any] = {
            "algo": c.algo,
            "fitness_measure": c.fitness,
            "generations": generations,
            "evaluation_seconds": round(seconds, 3),
            "policy_steps_per_second": round(steps / max(seconds, 1e-9)),
        }
        if self.final is not None:
            final = load_learner(self._final_folder() / "agent")
            figures["lineage_generations"] = final.generations
            champion = final.champion
            figures["champion_fitness"] = None if champion is None else champion.fitness
        return figures

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        return (
            f"{summary['algo']}, {summary['generations']} generations,"
            f" {summary['policy_steps_per_second'] / 1e6:.2f} M policy-steps/s;"
            f" {super().headline(summary)}"
        )

"""What a curriculum run reports: ``summary.json``'s figures, its agent, its pictures.

:class:`CurriculumSummary` is the reporting part of
:class:`~amaze.runs.curriculum.CurriculumRun` (which plays the loop): the
figures of ``summary.json`` (the stages played, the final lineage, the final
training, where the time went), how the agent was chosen and why the run
stopped early, the headline, and ``curriculum.png`` / ``progress.png``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from amaze.curriculum.curators import Candidate, StageRecord
from amaze.curriculum.regimes import OPEN_STAGES
from amaze.maze import rotations
from amaze.runs.branches import FINAL_FOLDER, branch_folder, time_spent
from amaze.runs.decisions import Decisions, advice_taken

__all__ = ["CurriculumSummary"]


class CurriculumSummary:
    """The records of a curriculum run and what it reports (see the module docstring).

    A base of :class:`~amaze.runs.curriculum.CurriculumRun`, whose loop fills
    the records (``records``, ``final``, ``finishing``) this class reads.
    """

    config: Any
    out: Path
    records: list[StageRecord]
    final: Candidate | None
    finishing: Candidate | None
    ended_because: str
    decided: Decisions

    def learner_figures(self) -> dict[str, Any]:
        """The trainer's entries of ``summary.json`` (algorithm, robot...)."""
        return {}

    def _lineage_mazes(self) -> list[str]:
        """The own mazes of the selected branches so far, newest first, each once."""
        mazes: list[str] = []
        for record in reversed(self.records):
            if record.selected is not None:
                maze = record.candidates[record.selected].mazes[0]
                if maze not in mazes:
                    mazes.append(maze)
        return mazes

    def _steps(self, current: Sequence[Candidate] = ()) -> int:
        """Env steps of every finished branch (and of ``current``, the stage in progress)."""
        done = sum(k.env_steps for record in self.records for k in record.candidates)
        finishing = self.finishing.env_steps if self.finishing is not None else 0
        return done + finishing + sum(k.env_steps for k in current)

    def _seconds(self, current: Sequence[Candidate] = ()) -> float:
        """Seconds of every finished branch (and of ``current``, the stage in progress)."""
        done = sum(k.seconds for record in self.records for k in record.candidates)
        finishing = self.finishing.seconds if self.finishing is not None else 0.0
        return done + finishing + sum(k.seconds for k in current)

    def _branch_folder(self, candidate_or_stage: Candidate | int, branch: int = 0) -> Path:
        if isinstance(candidate_or_stage, Candidate):
            stage, branch = candidate_or_stage.stage, candidate_or_stage.branch
        else:
            stage = candidate_or_stage
        return branch_folder(self.out, stage, branch)

    def agent_figures(self) -> dict[str, Any]:
        assert self.final is not None
        last = self.finishing or self.final
        done = [k for record in self.records for k in record.candidates]
        found = sum(k.env_steps for k in done if (k.stage, k.branch) <= (last.stage, last.branch))
        rule = f"the curator's final choice ({self.config.curator})"
        if self.finishing is not None:
            rule += ", then trained on its lineage's mazes"
            found += self.finishing.env_steps
        untrained = last.lineage_steps == 0
        return {"agent_rule": rule, "agent_steps": found, "agent_untrained": untrained}

    def stop_reason(self) -> str:
        c = self.config
        if self.ended_because:
            return self.ended_because
        if self.finishing is not None and self.finishing.converged:
            return (
                "the final agent converged on its lineage's mazes (every episode optimal) after"
                f" {self.finishing.env_steps:,} steps of final training"
            )
        converged = sum(k.converged for record in self.records for k in record.candidates)
        played = sum(len(record.candidates) for record in self.records)
        why = f"every stage played, {converged} of {played} branches converged early"
        if not c.final_training:
            why += "; final_training is off"
        return why

    def figures(self) -> dict[str, Any]:
        c = self.config
        budget_seconds = getattr(c, "budget_seconds", None)
        assert self.final is not None
        stages = []
        for record in self.records:
            chosen = record.candidates[record.selected] if record.selected is not None else None
            stages.append(
                {
                    "stage": record.stage,
                    "mazes": list(record.mazes),
                    "selected": record.selected,
                    "success_rate": None if chosen is None else chosen.success_rate,
                    "normalized_reward": None if chosen is None else chosen.normalized_reward,
                    "env_steps": sum(candidate.env_steps for candidate in record.candidates),
                }
            )
        return {
            **self.learner_figures(),
            "robot": c.robot,
            "seed": c.seed,
            "regime": c.regime,
            "curator": c.curator,
            "advisor": getattr(c, "advisor", None),
            "advice": advice_taken(self.decided.log.read(c.stages, c.branches, c.error)),
            "stages": c.stages,
            "stages_played": len(self.records),
            "branches": c.branches,
            "epochs": c.epochs,
            "rehearsal": c.rehearsal,
            "target": c.target,
            "replay_of": c.replay,
            "budget_steps": c.budget_steps,
            "budget_seconds": budget_seconds,
            "env_steps": self._steps(),
            "seconds": round(self._seconds(), 3),
            "time": time_spent(self._result_folders(), self.config.error),
            "final_lineage": list(self.final.lineage),
            "final_mazes": list(self.final.mazes),
            "final_training": None
            if self.finishing is None
            else {
                "mazes": list(self._lineage_mazes()),
                "env_steps": self.finishing.env_steps,
                "converged": self.finishing.converged,
                "success_rate": self.finishing.success_rate,
                "normalized_reward": self.finishing.normalized_reward,
            },
            "curriculum": stages,
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The final agent in the 4 rotations of the target maze."""
        mazes = rotations(self.config.target)
        return [(f"target-rotation-{index}", maze) for index, maze in enumerate(mazes)]

    def extra_outputs(self) -> None:
        from amaze.curriculum.picture import save_curriculum_png, save_curriculum_progress

        save_curriculum_png(self.records, self.out / "curriculum.png", title=self._title())
        save_curriculum_progress(
            self.records, self.config.target, self.out / "progress.png", title=self._title()
        )

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        played = summary.get("stages_played", summary["stages"])
        stages = f"{played} stages" + (" (open-ended)" if summary["stages"] == OPEN_STAGES else "")
        lineage = summary["final_lineage"]
        if len(lineage) > 12:
            lineage = (
                f"[{', '.join(map(str, lineage[:3]))}, ... {', '.join(map(str, lineage[-3:]))}]"
            )
        return (
            f"{summary['regime']} ({summary['curator']}, {stages} x"
            f" {summary['branches']} branches), final lineage {lineage};"
            f" {super().headline(summary)}"
        )

    def _title(self) -> str:
        c = self.config
        stages = "open-ended stages" if c.open_ended else f"{c.stages} stages"
        return f"{c.regime} / {c.curator}, seed {c.seed}: {stages} x {c.branches}"

    def _result_folders(self) -> list[Path]:
        """The folders of every branch played, the final training's included."""
        folders = [self._branch_folder(k) for record in self.records for k in record.candidates]
        if self.finishing is not None:
            folders.append(self.out / FINAL_FOLDER)
        return folders

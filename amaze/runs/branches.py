"""The branches of a curriculum run in its folder: results, records, progress.

A branch lives in ``stages/stage-<s>/branch-<b>/`` (:func:`branch_folder`;
a curriculum's final training in :data:`FINAL_FOLDER`): its ``result.json``
(a :class:`~amaze.curriculum.curators.Candidate` and its figures, written
last), its ``branch.json`` (what it started with, :data:`BRANCH_FILE`), its
``agent/`` and, while it trains, its ``checkpoint/``. This module reads
and writes those files, every value checked; the loop that trains branches
is :mod:`amaze.runs.curriculum`.
"""

from __future__ import annotations

import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from amaze.agents.trajectories import save_trajectory_png
from amaze.curriculum.curators import (
    Candidate,
    MazeResults,
)
from amaze.evaluation.policy import record_episode
from amaze.evaluation.protocol import Evaluator
from amaze.maze.spec import MazeSpec
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_json
from amaze.runs.lifecycle import check_digest
from amaze.validation import check_integer, check_number

__all__ = [
    "BRANCH_FILE",
    "BRANCH_FOLDER_PATTERN",
    "FINAL_FOLDER",
    "PICTURE_SIDE",
    "BranchProgress",
    "Clock",
    "branch_folder",
    "branch_folders",
    "candidate_from_dict",
    "candidate_to_dict",
    "check_branch_record",
    "maze_results",
    "new_candidate",
    "read_result",
    "save_branch_trajectory",
    "time_spent",
    "write_result",
]

#: About the side, in pixels, of a branch's trajectory picture.
PICTURE_SIDE = 320


@dataclass(frozen=True)
class BranchProgress:
    """How far a branch's training is, as :meth:`CurriculumRun.branch_progress` hears it."""

    stage: int
    branch: int
    #: Env steps the branch has spent in its session so far.
    steps: int
    #: Its allowance: env steps and/or seconds (``None``: no limit of that kind).
    budget_steps: int | None
    budget_seconds: float | None
    #: True once the branch is finished (trained, evaluated, its result written).
    done: bool = False


#: A branch folder, relative to the run folder.
BRANCH_FOLDER_PATTERN = re.compile(r"stages/stage-(0|[1-9][0-9]*)/branch-(0|[1-9][0-9]*)")
#: What a branch in training records when it starts (its ``checkpoint/`` continues only that).
BRANCH_FILE = "branch.json"
#: The folder of the final training (``final_training``), relative to the run folder.
FINAL_FOLDER = "stages/final"


def branch_folder(out: Path, stage: int, branch: int) -> Path:
    """Where the loop keeps a branch of the run in ``out``: ``stages/stage-<s>/branch-<b>``."""
    return Path(out) / "stages" / f"stage-{stage}" / f"branch-{branch}"


def maze_results(evaluator: Evaluator, agent: Any, mazes: Sequence[str]) -> list[MazeResults]:
    """``agent`` on ``mazes``, each in its 4 rotations (``evaluator`` holds those, in order)."""
    episodes = evaluator.evaluate(agent).episodes
    return [
        MazeResults(
            maze=maze,
            success=tuple(e.success for e in episodes[4 * index : 4 * index + 4]),
            normalized_reward=tuple(
                e.normalized_reward for e in episodes[4 * index : 4 * index + 4]
            ),
            steps=tuple(e.steps for e in episodes[4 * index : 4 * index + 4]),
        )
        for index, maze in enumerate(mazes)
    ]


def _count(data: Mapping[str, Any], key: str) -> int:
    """``data[key]``, a non-negative integer (``ValueError`` otherwise)."""
    return check_integer(key, data[key], minimum=0)


def candidate_from_dict(data: Mapping[str, Any], folder: Path) -> Candidate:
    """A candidate read from ``result.json`` (any missing, ill-typed or impossible value raises)."""
    if not isinstance(data["mazes"], list) or len(data["mazes"]) != 1:
        raise ValueError(f"mazes {data['mazes']!r} is not a list of one maze")
    mazes = tuple(str(m) for m in data["mazes"])
    results = [MazeResults.from_dict(r) for r in data["results"]]
    branch = int(data["branch"])  # results come in branch order: two branches may share a maze
    if not 0 <= branch < len(results) or results[branch].maze not in mazes:
        raise ValueError(f"branch {branch} has no results of its own maze")
    lineage = tuple(check_integer("lineage", b, minimum=0) for b in data["lineage"])
    stage = _count(data, "stage")
    if len(lineage) != stage + 1 or lineage[-1] != branch:
        raise ValueError(f"lineage {list(lineage)} is not that of branch {branch} of stage {stage}")
    env_steps, lineage_steps = _count(data, "env_steps"), _count(data, "lineage_steps")
    if lineage_steps < env_steps:
        raise ValueError(f"lineage_steps {lineage_steps} is less than env_steps {env_steps}")
    if not isinstance(data["converged"], bool):
        raise ValueError(f"converged {data['converged']!r} is not true or false")
    time = data.get("time", {})
    if not isinstance(time, dict):
        raise ValueError(f"time {time!r} is not an object")
    for part, seconds in time.items():
        check_number(f"time {part}", seconds, minimum=0)
    return Candidate(
        stage=stage,
        branch=branch,
        mazes=mazes,
        own=(results[branch],),
        others=tuple(r for i, r in enumerate(results) if i != branch),
        lineage=lineage,
        env_steps=env_steps,
        seconds=check_number("seconds", data["seconds"], minimum=0),
        converged=data["converged"],
        lineage_steps=lineage_steps,
        pictures=tuple(folder / str(p) for p in data.get("pictures", [])),
        validation=tuple(MazeResults.from_dict(r) for r in data.get("validation", [])),
    )


def candidate_to_dict(candidate: Candidate, results: Sequence[MazeResults]) -> dict[str, Any]:
    return {
        "stage": candidate.stage,
        "branch": candidate.branch,
        "mazes": list(candidate.mazes),
        "results": [r.to_dict() for r in results],
        "lineage": list(candidate.lineage),
        "env_steps": candidate.env_steps,
        "seconds": round(candidate.seconds, 3),
        "converged": candidate.converged,
        "lineage_steps": candidate.lineage_steps,
        "pictures": [p.name for p in candidate.pictures],
        "validation": [r.to_dict() for r in candidate.validation],
        "success_rate": candidate.success_rate,
        "normalized_reward": candidate.normalized_reward,
    }


def branch_folders(out: Path) -> list[Path]:
    """The folders ``stages/stage-<s>/branch-<b>`` of the run in ``out``, in the loop's order.

    Other names under ``stages/`` are not the loop's and are left alone.
    """
    folders = []
    for folder in out.glob("stages/stage-*/branch-*"):
        if BRANCH_FOLDER_PATTERN.fullmatch(folder.relative_to(out).as_posix()):
            folders.append(folder)
    return sorted(folders, key=lambda f: (int(f.parent.name[6:]), int(f.name[7:])))


def read_result(
    folder: Path,
    error: type[ValueError],
    config_digest: str,
    expected: tuple[int, int] | None = None,
) -> Candidate:
    """The finished branch in ``folder``, its ``result.json`` checked; ``error`` naming it else.

    It must be the branch of the folder's name, or the ``(stage, branch)``
    ``expected`` (the final training's), and have been written under the
    run's config (``config_digest``, :attr:`~amaze.runs.lifecycle.Run.config_digest`).
    """
    path = folder / "result.json"
    data = read_json_object(path, error, "branch result")
    try:
        candidate = candidate_from_dict(data, folder)
    except (KeyError, TypeError, ValueError) as problem:
        raise error(
            f"branch result {str(path)!r} is damaged ({type(problem).__name__}: {problem})"
        ) from None
    found = (candidate.stage, candidate.branch)
    if found != (expected or found) or (
        expected is None and branch_folder(folder.parents[2], *found) != folder
    ):
        raise error(
            f"branch result {str(path)!r} says stage {found[0]} branch {found[1]}: it is in"
            " another branch's folder"
        )
    check_digest(data.get("config_sha256"), config_digest, f"branch result {str(path)!r}", error)
    return candidate


def check_branch_record(folder: Path, started: Mapping[str, Any], error: type[ValueError]) -> None:
    """The branch in training in ``folder`` was started as the loop would start it now.

    Its ``branch.json`` recorded its mazes, parent, allowance and config
    when it started (``started`` is what the loop would record now): a
    checkpoint goes on only with the same, since the learner would otherwise
    continue a session on other mazes, from another parent or with another
    budget (decisions or results edited since, or another config).
    """
    path = folder / BRANCH_FILE
    where = f"branch record {str(path)!r}"
    if not (path.exists() or path.is_symlink()):
        raise error(f"{where} is missing: the checkpoint beside it cannot be checked")
    recorded = read_json_object(path, error, "branch record")
    changed = sorted(key for key in started if recorded.get(key) != started[key])
    if changed:
        name = changed[0]
        raise error(
            f"{where}: the branch in training started with {name} {recorded.get(name)!r},"
            f" but the run's decisions, results and config now give {started[name]!r}"
            f" ({', '.join(changed)} changed since): its checkpoint cannot go on"
        )


def time_spent(folders: Sequence[Path], error: type[ValueError]) -> dict[str, float]:
    """Seconds of the branches in ``folders`` by part (training, evaluation...), summed."""
    totals: dict[str, float] = {}
    for folder in folders:
        data = read_json_object(folder / "result.json", error, "branch result")
        for part, seconds in data.get("time", {}).items():
            totals[part] = round(totals.get(part, 0.0) + float(seconds), 3)
    return totals


class Clock:
    """Seconds spent by part (``lap("evaluation")``: since the last lap or skip, to that part)."""

    def __init__(self) -> None:
        self.last = time.perf_counter()
        self.parts: dict[str, float] = {}

    def lap(self, part: str) -> None:
        now = time.perf_counter()
        self.parts[part] = self.parts.get(part, 0.0) + now - self.last
        self.last = now

    def skip(self) -> None:
        """Count nothing since the last lap (time another counter keeps)."""
        self.last = time.perf_counter()


def save_branch_trajectory(folder: Path, maze: str, robot: str, agent: Any) -> Path:
    """``trajectory.png``: ``agent`` in the branch's own ``maze``, small and quick to draw."""
    _, trajectory = record_episode(maze, robot, agent)
    picture = folder / "trajectory.png"
    spec = MazeSpec.from_string(maze)
    cell = max(8, PICTURE_SIDE // max(spec.width, spec.height))
    save_trajectory_png(spec, trajectory, picture, robot=robot, caption=True, cell_size=cell)
    return picture


def new_candidate(
    stage: int,
    branch: int,
    mazes: Sequence[str],
    results: Sequence[MazeResults],
    validation: Sequence[MazeResults],
    parent: Candidate | None,
    outcome: Any,
    spent: Mapping[str, float],
    picture: Path,
) -> Candidate:
    """The candidate a branch trained to ``outcome`` is (results in branch order)."""
    lineage = (*parent.lineage, branch) if parent is not None else (branch,)
    parent_steps = parent.lineage_steps if parent is not None else 0
    return Candidate(
        stage=stage,
        branch=branch,
        mazes=(mazes[branch],),
        own=(results[branch],),
        others=tuple(r for i, r in enumerate(results) if i != branch),
        lineage=lineage,
        env_steps=outcome.env_steps,
        # rounded as result.json keeps it, so a resumed run shares time alike
        seconds=round(sum(spent.values()), 3),
        converged=outcome.converged,
        lineage_steps=parent_steps + outcome.env_steps,
        pictures=(picture,),
        validation=tuple(validation),
    )


def write_result(
    folder: Path,
    candidate: Candidate,
    results: Sequence[MazeResults],
    spent: Mapping[str, float],
    training: Sequence[str],
    config_digest: str,
) -> None:
    """``result.json``: the finished branch, written last (a branch with one is finished)."""
    data = candidate_to_dict(candidate, results)
    data["time"] = {part: round(seconds, 3) for part, seconds in spent.items()}
    data["training_mazes"] = list(training)
    data["config_sha256"] = config_digest
    write_json(folder / "result.json", data)

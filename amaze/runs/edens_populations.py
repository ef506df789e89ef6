"""EDEnS over co-evolved maze populations as a run (the ``edens-populations`` regime).

::

    every epoch:
        parent <- the learner's state and the maze population
        controllers <- the parent's, then m - 1 mutants of it      # population_selector
        for each alternative i:
            the learner and the population start again from parent (a copy),
            the population steered by controllers[i]
            play `epoch` rounds of the co-evolution loop           # learn, score, admit
            its agents on the validation mazes (its last round)    # the criteria
        keep one alternative from the Pareto front of the criteria (seeded pick,
        extinct ones rejected); its learner and population go on

:class:`EdensPopulationsRun` is that loop on the co-evolution loop
(:class:`~amaze.runs.coevolution.CoevolutionRun`): a trainer adds only how its
learner is copied (:meth:`EdensPopulationsRun.learner`,
:meth:`~EdensPopulationsRun.adopt_learner`). Every round of every alternative
is a round of the run: its env steps and seconds count in the budget, it is a
row of ``progress.csv`` (with its ``epoch`` and ``alternative``), and its
validation may make the run's champion (the best on the validation mazes
so far, whichever alternative played it). A budget spent in the middle of an
epoch ends the run there, with the champion as its agent.

Alternatives share the population's generated mazes
(:meth:`~amaze.curriculum.maze_population.MazePopulation.branch`): a maze is
generated and compiled once, whichever alternative meets it.

**Outputs**, besides the co-evolution loop's: ``epochs.jsonl``, one JSON
object per decided epoch: the round and env steps at its end, every
alternative's controller (the population options it ran with), the fields
mutated, its criteria, whether it was extinct and on the front, and the
chosen alternative; ``epochs.png``, the alternatives' validation success
and the chosen controller over the epochs; ``summary.json``'s ``selector`` (the options),
``epochs`` (decided), ``controller`` (the population options the run ended
with) and ``chosen_alternatives`` (how often each alternative was kept).
Same config and seed give the same choices (every draw comes from the run's
seed; :func:`~amaze.curriculum.population_selector.selector_rng`).

**Replay.** ``--replay RUN_DIR`` starts a new run with RUN_DIR's config and
its recorded picks (its ``epochs.jsonl``, copied to ``replay.jsonl``) in place
of the selector's draws, as a curriculum replays its curator's decisions: an
unchanged file gives the same run, bit for bit; a file whose ``chosen`` was
changed (a person overruling the selector) makes the run keep that
alternative, on the front or not. Such epochs say ``"replayed": true``.
"""

from __future__ import annotations

import copy
import dataclasses
import json
from abc import abstractmethod
from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from amaze.curriculum.maze_population import MazePopulation
from amaze.curriculum.population_selector import (
    Outcome,
    SelectorConfig,
    SelectorState,
    choose,
    controller_of,
    criteria_values,
    mutate_controller,
    selector_rng,
)
from amaze.maze import Maze
from amaze.runs.branches import Clock
from amaze.runs.coevolution import BatchResults, CoevolutionRun, CoevolutionState
from amaze.runs.config import RunConfig
from amaze.runs.epochs_picture import save_epochs_plot
from amaze.runs.folder import read_text, write_bytes
from amaze.validation import parse_json

__all__ = ["EPOCHS_FILE", "EPOCH_FIELDS", "REPLAY_FILE", "EdensPopulationsRun", "read_picks"]

#: The ``progress.csv`` columns this regime adds after the trainer's.
EPOCH_FIELDS = ("epoch", "alternative")
#: The selector's record of a run, and a replaying run's copy of the replayed run's.
EPOCHS_FILE = "epochs.jsonl"
REPLAY_FILE = "replay.jsonl"


def read_picks(path: Path, alternatives: int, error: type[ValueError]) -> tuple[list[int], str]:
    """The chosen alternative of every epoch of an ``epochs.jsonl``, and the file's text.

    Each line must be the JSON object of the next epoch (``epoch`` 0, 1...)
    with ``chosen`` one of the ``alternatives``; ``error`` names a bad line.
    """
    where = repr(str(path))
    if not (path.exists() or path.is_symlink()):
        raise error(f"epochs file {where} is missing")
    text = read_text(path, error, "epochs file")
    picks: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            data = parse_json(line, "the line", error=ValueError)
        except ValueError as problem:
            raise error(f"epochs file {where}, line {number}: {problem}") from None
        epoch = data.get("epoch") if isinstance(data, dict) else None
        chosen = data.get("chosen") if isinstance(data, dict) else None
        if epoch != len(picks) or isinstance(epoch, bool):
            raise error(
                f"epochs file {where}, line {number}: epoch {epoch!r} is not {len(picks)},"
                " the next epoch"
            )
        if isinstance(chosen, bool) or not isinstance(chosen, int):
            raise error(f"epochs file {where}, line {number}: chosen {chosen!r} is not a number")
        if not 0 <= chosen < alternatives:
            raise error(
                f"epochs file {where}, line {number}: chosen {chosen} is not one of the"
                f" {alternatives} alternatives"
            )
        picks.append(chosen)
    return picks, text


class EdensPopulationsRun(CoevolutionRun):
    """The co-evolution loop under an EDEnS selector (see the module docstring)."""

    outputs: ClassVar[tuple[str, ...]] = (*CoevolutionRun.outputs, EPOCHS_FILE, "epochs.png")
    #: The picks of the run this one replays (``--replay``), in epoch order; empty otherwise.
    replayed: list[int]
    #: The text they were read from, written as the run's ``replay.jsonl``.
    replayed_text: str = ""

    # -- the trainer's part ---------------------------------------------------

    @abstractmethod
    def learner(self) -> Any:
        """The learner's state that an alternative copies (a search algorithm...)."""

    @abstractmethod
    def adopt_learner(self, learner: Any) -> None:
        """Make ``learner`` (one :meth:`learner` gave, or a copy of it) the run's learner."""

    # -- the selector -----------------------------------------------------------

    @cached_property
    def selector(self) -> SelectorConfig:
        """The selector's options (the config's ``selector``, checked by it)."""
        return SelectorConfig.from_dict(self.config.selector)

    @classmethod
    def replay_config(cls, source: Path, config: RunConfig) -> RunConfig:
        """``source``'s config, marked as its replay, once its finished ``epochs.jsonl`` checks."""
        c: Any = config
        if not (source / "summary.json").exists():
            raise c.error(f"{str(source)!r} holds an unfinished run (resume it first)")
        alternatives = SelectorConfig.from_dict(c.selector).alternatives
        read_picks(source / EPOCHS_FILE, alternatives, c.error)
        return dataclasses.replace(c, replay=str(source))

    def start(self) -> None:
        super().start()
        self._read_replayed()

    def restore(self) -> int | None:
        self._read_replayed()
        return super().restore()

    def _read_replayed(self) -> None:
        """A replay's picks: from the run's own copy once it has one, else the replayed run's."""
        c = self.config
        self.replayed = []
        if c.replay is None:
            return
        alternatives = self.selector.alternatives
        copied = self.out / REPLAY_FILE
        source = copied if copied.exists() else Path(c.replay) / EPOCHS_FILE
        self.replayed, self.replayed_text = read_picks(source, alternatives, c.error)

    @property
    def selection(self) -> SelectorState:
        selection = self.state.selection
        assert isinstance(selection, SelectorState)
        return selection

    def new_state(self, mazes: MazePopulation) -> CoevolutionState:
        state = super().new_state(mazes)  # type: ignore[safe-super]
        state.selection = SelectorState()
        return state

    def validation_due(self) -> bool:
        """Every ``validation_every``-th round, as in co-evolution, and an alternative's last.

        The last round of an alternative's epoch gives its criteria.
        """
        last = self.selection.played + 1 == self.selector.epoch
        return last or super().validation_due()

    def learn(self, mazes: list[Maze], clock: Clock) -> BatchResults:
        """The trainer's step, noting whether a goal was reached and which alternative played."""
        played = super().learn(mazes, clock)  # type: ignore[safe-super]
        selection = self.selection
        selection.solved = selection.solved or bool(np.any(played.success))
        played.figures.update(epoch=selection.epoch, alternative=selection.current)
        return played

    def play_round(self) -> dict[str, Any]:
        """A round of the current alternative; its epoch's end judges it, the last one decides."""
        selection = self.selection
        if not selection.under_way:
            self._begin_epoch()
        row = super().play_round()
        selection.played += 1
        if selection.played == self.selector.epoch:
            self._end_alternative(row)
        return row

    def _begin_epoch(self) -> None:
        """The parent is the state now; draw the alternatives' controllers; start the first."""
        c, s, selection, options = self.config, self.state, self.selection, self.selector
        rng = selector_rng(c.seed, selection.epoch, "controllers")
        parent = s.mazes.config
        mutants = [
            mutate_controller(parent, c.target, rng, options.mutations)
            for _ in range(options.alternatives - 1)
        ]
        # the state now is the parent, kept as it is: each alternative plays a copy of it
        selection.parent_learner = self.learner()
        selection.parent_mazes = s.mazes
        selection.controllers = [parent, *(config for config, _ in mutants)]
        selection.mutated = [(), *(names for _, names in mutants)]
        selection.current, selection.outcomes = 0, []
        self._start_alternative()

    def _start_alternative(self) -> None:
        """The current alternative: a copy of the parent, steered by its controller.

        The first keeps the parent population's random stream; the others draw
        from streams of their own.
        """
        c, selection = self.config, self.selection
        index = selection.current
        seed = None
        if index:
            stream = selector_rng(c.seed, selection.epoch, f"population {index}")
            seed = int(stream.integers(2**63))
        assert selection.parent_mazes is not None
        self.state.mazes = selection.parent_mazes.branch(selection.controllers[index], seed)
        self.adopt_learner(copy.deepcopy(selection.parent_learner))
        selection.played, selection.solved = 0, False

    def _end_alternative(self, row: Mapping[str, Any]) -> None:
        """Record the alternative's criteria; start the next one or decide the epoch."""
        s, selection = self.state, self.selection
        index = selection.current
        success_rate = float(row["validation_success_rate"])
        selection.outcomes.append(
            Outcome(
                index=index,
                controller=selection.controllers[index],
                mutated=selection.mutated[index],
                criteria=criteria_values(s.mazes, success_rate, float(row["validation"])),
                solved=selection.solved or success_rate > 0,
                learner=self.learner(),
                mazes=s.mazes,
            )
        )
        if index + 1 < self.selector.alternatives:
            selection.current = index + 1
            self._start_alternative()
        else:
            self._decide()

    def _decide(self) -> None:
        """Keep one alternative (extinct ones rejected, a seeded pick from the Pareto front)."""
        c, s, selection = self.config, self.state, self.selection
        rng = selector_rng(c.seed, selection.epoch, "select")
        chosen, front, alive = choose(selection.outcomes, self.selector.criteria, rng)
        replayed = selection.epoch < len(self.replayed)
        if replayed:
            chosen = selection.outcomes[self.replayed[selection.epoch]]
        assert chosen.mazes is not None
        s.mazes = chosen.mazes
        self.adopt_learner(chosen.learner)
        on_front = {o.index for o in front}
        living = {o.index for o in alive}
        selection.decisions.append(
            {
                "epoch": selection.epoch,
                self.position_field: s.round,
                "steps": s.steps,
                "chosen": chosen.index,
                "replayed": replayed,
                "front": sorted(on_front),
                "alternatives": [
                    {
                        "index": o.index,
                        "controller": controller_of(o.controller),
                        "mutated": list(o.mutated),
                        **{k: round(v, 6) for k, v in o.criteria.items()},
                        "extinct": o.index not in living,
                        "on_front": o.index in on_front,
                    }
                    for o in selection.outcomes
                ],
            }
        )
        selection.epoch += 1
        selection.parent_learner = selection.parent_mazes = None
        selection.controllers, selection.mutated, selection.outcomes = [], [], []
        selection.current = selection.played = 0

    # -- outputs ----------------------------------------------------------------

    def write_epochs(self) -> Path:
        """``epochs.jsonl`` (one line per decided epoch), and a replay's ``replay.jsonl`` once."""
        c = self.config
        if c.replay is not None and not (self.out / REPLAY_FILE).exists():
            write_bytes(self.out / REPLAY_FILE, self.replayed_text.encode("utf-8"))
        lines = [json.dumps(d, sort_keys=False) + "\n" for d in self.selection.decisions]
        return write_bytes(self.out / EPOCHS_FILE, "".join(lines).encode("utf-8"))

    def save_checkpoint(self) -> None:
        super().save_checkpoint()
        self.write_epochs()

    def extra_outputs(self) -> None:
        """The co-evolution loop's, ``epochs.jsonl`` and ``epochs.png``."""
        c = self.config
        super().extra_outputs()
        self.write_epochs()
        title = f"{c.algo}, {c.regime}, seed {c.seed}: {self.selection.epoch} epochs"
        save_epochs_plot(self.selection.decisions, self.out / "epochs.png", c.target, title)

    def figures(self) -> dict[str, Any]:
        """The loop's figures, the selector's options, the epochs and the controller reached."""
        selection = self.selection
        chosen = [d["chosen"] for d in selection.decisions]
        counts = np.bincount(np.array(chosen, dtype=int), minlength=self.selector.alternatives)
        return {
            **super().figures(),
            "selector": self.selector.to_dict(),
            "epochs": selection.epoch,
            "epoch_under_way": (
                {"alternative": selection.current, self.position_field + "s": selection.played}
                if selection.under_way
                else None
            ),
            "controller": controller_of(self.state.mazes.config),
            "chosen_alternatives": counts.tolist(),
        }

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        return f"{summary['epochs']} epochs decided; {super().headline(summary)}"

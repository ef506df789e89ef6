"""A curator of your own, plugged into an EDHuCAT curriculum run from Python.

In the EDHuCAT loop (docs: "EDHuCAT and curators") a curriculum is a series of
stages; at each one, K copies of the current agent (branches) train on K new
mazes, and a *curator* makes the loop's two decisions:

* ``select(candidates) -> candidate``: which branch's agent goes on;
* ``generate(k, history) -> k maze strings``: the next stage's mazes.

The curator below, ``grow``, makes a maze harder only once it is mastered:
while the selected agent has not solved its own maze in all 4 rotations, its
branches get that maze again with new walls (new seeds); once it has, they get
it with intersections and the target's clues, then a few cells larger, toward
the target's size. It selects the branch that does best on mazes of the
target's family that no branch trained on (its ``validation`` mazes, which
the loop plays every candidate on).

Curators are found by name, among the built-in ones and those that installed
distributions declare under the entry-point group ``amaze.curators``
(docs: "Curator plug-ins"). A package declares it in its ``pyproject.toml``;
this one-file script writes the same declaration (a ``.dist-info`` folder)
into a temporary folder put on ``sys.path``. The run itself is
:func:`evolution.run.evolve` with CMA-ES, as ``amaze-evolve --regime edhucat
--curator grow`` runs it once the plug-in is installed.

Run it::

    python examples/custom_curator.py           # 8 stages of 3 branches: about 10 s on 2 cores
    python examples/custom_curator.py --tiny    # 2 stages, a few generations: a smoke test

Needs only the project's dependencies.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    History,
    curator_names,
    refuse_unknown_options,
)
from amaze.curriculum.validation import unseen_mazes, validation_mazes
from amaze.evaluation.protocol import evaluate
from amaze.maze import MazeSpec
from evolution.config import EvolveConfig
from evolution.run import evolve

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--tiny", action="store_true", help="2 stages, a few generations (tests)")
parser.add_argument("--target", default="M4_10x10_C1", help="the maze the curriculum leads to")
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()

# -- the curator -------------------------------------------------------------------


class GrowCurator:
    """Harder mazes once the current one is mastered: intersections first, then size."""

    name = "grow"

    def __init__(self, context: CuratorContext) -> None:
        # context: the target maze, the run's seed, stages, branches, robot and options
        refuse_unknown_options(context, self.name, known=("step",))  # a typo is an error
        self.context = context
        self.step = int(context.options.get("step", 2))  # cells added per side at a time
        # mazes of the target's family with seeds apart from the evaluation suite's; the
        # loop plays every candidate on their 4 rotations (Candidate.validation)
        self.validation = validation_mazes(context.target, 4, seed=context.seed)

    def select(self, candidates: Sequence[Candidate]) -> Candidate:
        """The best on the validation mazes (success, then R̄), then on its own maze."""
        return max(
            candidates,
            key=lambda c: (
                c.validation_success_rate,
                c.validation_normalized_reward,
                c.normalized_reward,
            ),
        )

    def generate(self, k: int, history: History) -> list[str]:
        parent = MazeSpec.from_string(history.mazes[0])  # the maze the selected agent learnt
        target = MazeSpec.from_string(self.context.target)
        maze = parent
        if history.parent.solved:  # goal reached in all 4 rotations: one challenge more
            if parent.unicursive and not target.unicursive:
                maze = dataclasses.replace(parent, unicursive=False, clue=target.clue)
            else:
                maze = dataclasses.replace(
                    parent,
                    width=min(parent.width + self.step, target.width),
                    height=min(parent.height + self.step, target.height),
                )
        # randomness only from the context's generator: a resumed run decides the same
        seeds = self.context.rng(history.stage, "generate").integers(0, 2**31, size=k)
        return [dataclasses.replace(maze, seed=int(seed)).to_string() for seed in seeds]


# -- declaring it, as an installed distribution would ---------------------------------

scratch = tempfile.TemporaryDirectory()  # the plug-in's declaration and the run folder
plugins = Path(scratch.name) / "plugins"
dist_info = plugins / "grow_curator-0.1.dist-info"
dist_info.mkdir(parents=True)
(dist_info / "METADATA").write_text("Metadata-Version: 2.1\nName: grow-curator\nVersion: 0.1\n")
# the class lives in this script, which runs as the module __main__
(dist_info / "entry_points.txt").write_text("[amaze.curators]\ngrow = __main__:GrowCurator\n")
sys.path.insert(0, str(plugins))
importlib.invalidate_caches()
print(f"curators: {', '.join(curator_names())}")  # ..., follow, grow

# -- an EDHuCAT run with CMA-ES, from Python ------------------------------------------

config = EvolveConfig(
    regime="edhucat",
    curator="grow",
    curator_options={"step": 2},  # GrowCurator's option (context.options)
    target=args.target,
    stages=2 if args.tiny else 8,  # the first stage trains on a trivial 5x5 maze
    branches=2 if args.tiny else 3,
    budget_steps=40_000 if args.tiny else 3_000_000,  # env steps, shared by the branches
    robot="DD",
    seed=args.seed,
)
out = Path(scratch.name) / "run"
started = time.perf_counter()
result = evolve(config, out)  # writes the run folder; its agent and summary.json's content
print(f"EDHuCAT with the curator 'grow' in {time.perf_counter() - started:.1f} s")

# decisions.jsonl: every decision of the run, one JSON object per line
for line in (out / "decisions.jsonl").read_text().splitlines():
    decision = json.loads(line)
    stage = decision["stage"]
    if decision["kind"] == "generate":
        print(f"  stage {stage} trains on: {', '.join(decision['mazes'])}")
    else:  # the select decision of stage s chooses among the branches of stage s - 1
        chosen = decision["candidates"][decision["choice"]] if "candidates" in decision else {}
        figures = (
            f" (own maze success {chosen['success_rate']:.2f},"
            f" validation success {chosen['validation_success_rate']:.2f})"
            if chosen
            else ""
        )
        print(f"  stage {stage - 1}: branch {decision['choice']} goes on{figures}")

summary = result.summary  # the final agent on the standard evaluation suite, and more
print(
    f"final agent, {result.env_steps:,} env steps: standard suite success rate"
    f" {summary['success_rate']:.2f}, mean R̄ {summary['normalized_reward']:+.3f}"
)
unseen = unseen_mazes(args.target, seed=args.seed, n=32)  # the target's family, never seen
report = evaluate(result.agent, "DD", unseen, rotations=4, inputs=False)
print(
    f"final agent on 32 unseen mazes like {args.target} x 4: success rate {report.success_rate:.2f}"
)
scratch.cleanup()

"""Neuroevolution in a few lines: CMA-ES asks, the batch engine plays, CMA-ES is told.

The search algorithm is the ``cma`` package's ``CMAEvolutionStrategy``, used
through its ask/tell interface; the agents are our own small numpy network
(8 inputs, a hidden layer, 4 outputs); they are scored by the project's
:class:`evolution.population.PopulationEvaluator`, which plays a whole
population at once on the numba :class:`~amaze.agents.engine.BatchEngine`.

A policy of the project (:mod:`amaze.evaluation.policy`) is any callable that
maps a batch of observations to a batch of actions. A *population* policy
holds P individuals and plays P x M episodes in one batch: agent ``k``
belongs to individual ``k // M`` (it says how many it holds with
``n_policies``, and hears M through ``reset(n_agents)``). Each generation::

    candidates = es.ask()                               # P parameter vectors
    result = evaluator.evaluate(Population(candidates)) # every individual on every maze
    es.tell(candidates, -result.fitness)                # CMA-ES minimises

The fitness is the mean of the paper's normalised reward R̄ over the training
mazes (1 on the shortest path). The champion is then scored, as any agent
is, with :func:`amaze.evaluation.protocol.evaluate`, on mazes it never saw.

Run it::

    python examples/evolution_ask_tell.py           # 200 generations: under a minute on 2 cores
    python examples/evolution_ask_tell.py --tiny    # 3 generations: a smoke test

Needs only the project's dependencies (cma, numpy, numba).
"""

from __future__ import annotations

import argparse
import time

import cma
import numpy as np

from amaze.curriculum.validation import unseen_mazes
from amaze.evaluation.protocol import evaluate
from amaze.maze import MazeSpec
from evolution.population import PopulationEvaluator

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--tiny", action="store_true", help="3 generations (for the tests)")
parser.add_argument("--maze", default="M4_10x10_C1", help="the family of the training mazes")
parser.add_argument("--generations", type=int, default=200)
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()
generations = 3 if args.tiny else args.generations

# -- the network: 8 inputs -> HIDDEN tanh units -> 4 action scores -----------------

INPUTS, HIDDEN, OUTPUTS = 8, 16, 4  # a DD robot sees 8 floats and moves E, N, W, S
N_PARAMS = INPUTS * HIDDEN + HIDDEN + HIDDEN * OUTPUTS + OUTPUTS


class Population:
    """P networks acting together: a population policy of ``amaze.evaluation.policy``."""

    robot = "DD"  # the evaluator checks that the population drives its robot

    def __init__(self, parameters: np.ndarray) -> None:
        parameters = np.atleast_2d(parameters)  # (P, N_PARAMS): one row per individual
        self.n_policies = len(parameters)
        sizes = [INPUTS * HIDDEN, HIDDEN, HIDDEN * OUTPUTS, OUTPUTS]
        w1, b1, w2, b2 = np.split(parameters, np.cumsum(sizes)[:-1], axis=1)
        self.w1 = w1.reshape(-1, INPUTS, HIDDEN)
        self.b1 = b1[:, None, :]
        self.w2 = w2.reshape(-1, HIDDEN, OUTPUTS)
        self.b2 = b2[:, None, :]
        self.episodes = 1

    def reset(self, n_agents: int) -> None:
        """Called before the first step: ``n_agents = P * M``."""
        self.episodes = n_agents // self.n_policies

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Observations ``(P * M, 8)`` -> actions ``(P * M,)``, individual by individual."""
        x = observations.reshape(self.n_policies, self.episodes, INPUTS)
        hidden = np.tanh(x @ self.w1 + self.b1)  # (P, M, HIDDEN): batched matrix products
        scores = hidden @ self.w2 + self.b2  # (P, M, 4)
        return scores.argmax(axis=-1).reshape(-1)


# -- the training mazes and the evaluator ---------------------------------------------

# 4 mazes of the family of args.maze: its fields with other seeds (so other walls)
train_mazes = [MazeSpec.from_string(args.maze, seed=100 + i).to_string() for i in range(4)]
# each training maze in its 4 rotations (the robot starts from each corner): M = 16 episodes
evaluator = PopulationEvaluator(train_mazes, "DD", rotations=True, fitness="normalized_reward")

# a start at 0 with step size 0.5, 32 individuals a generation; cma's seed 0 would mean "random"
options = {"popsize": 32, "seed": args.seed + 1, "verbose": -9}
es = cma.CMAEvolutionStrategy(np.zeros(N_PARAMS), 0.5, options)
print(
    f"CMA-ES on {N_PARAMS} parameters, population {es.popsize},"
    f" {len(train_mazes)} mazes like {args.maze} x 4 rotations"
)

# -- the ask / tell loop ----------------------------------------------------------------

started = time.perf_counter()
env_steps = 0
best_fitness, champion = -np.inf, np.zeros(N_PARAMS)
for generation in range(1, generations + 1):
    candidates = es.ask()  # a list of P parameter vectors
    result = evaluator.evaluate(Population(np.array(candidates)))
    es.tell(candidates, list(-result.fitness))  # CMA-ES minimises: tell it -fitness
    env_steps += result.env_steps
    if result.fitness.max() > best_fitness:
        best_fitness, champion = result.fitness.max(), np.array(candidates[result.best])
    if generation % 25 == 0 or generation == generations:
        print(
            f"generation {generation:4d}: best R̄ {result.fitness.max():+.3f},"
            f" mean {result.fitness.mean():+.3f}, champion {best_fitness:+.3f},"
            f" {env_steps:,} env steps"
        )
print(f"evolved in {time.perf_counter() - started:.1f} s")

# -- the champion, scored with the evaluation protocol ------------------------------------

champion_policy = Population(champion)  # a population of one is a plain policy
for name, mazes in (
    ("training mazes (4 x 4 rotations)", train_mazes),
    ("unseen mazes of the family (32 x 4)", unseen_mazes(args.maze, seed=args.seed, n=32)),
):
    report = evaluate(champion_policy, "DD", mazes, rotations=4, inputs=False)
    print(
        f"champion on {name}: success rate {report.success_rate:.2f},"
        f" mean R̄ {report.normalized_reward:+.3f}"
    )
suite = evaluate(champion_policy, "DD")  # the standard suite: 18 mazes x 4 rotations
print(
    f"champion on the standard suite: success rate {suite.success_rate:.2f},"
    f" mean R̄ {suite.normalized_reward:+.3f}, input recognition {suite.input_recognition:.2f}"
)

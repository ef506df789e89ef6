"""The JAX environment and the numba batch engine play the same episodes, step for step.

Mazes of every class (trivial, trivial with lures, simple, lures, traps,
complex; sizes 2..30 each way, rotated or not, with several sign shapes and
values), each in its four rotations (so from every start corner), are played
by one engine agent each and by one JAX environment each (``vmap`` over
stacked, padded params; one ``lax.scan`` over all steps, compiled once per
robot). Actions mix the oracle (``OracleController``, from the engine's cells)
and seeded random moves, with a different oracle share per environment, so
that episodes reach the goal, bump into walls, step back and run into the
deadline. The engine's actions are recorded and replayed in JAX: if a JAX
environment ever stood elsewhere, its observations would differ.

Compared at every step: observations, rewards, ``terminated`` and
``truncated``, bit for bit (rewards: JAX's float32 against the engine's float64
rounded to float32); at every episode end: the last observation and the
integer counters, exactly; the return and R̄ against the engine's float64
values rounded to float32 (exactly, in practice: see the bound in
:func:`check_scores`), and ``pretty_reward`` exactly except at near-ties of its
rounding to 3 decimals, where it may differ by 0.001.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.agents.rewards import RewardScheme
from amaze.envs.jax import make_batch
from amaze.evaluation.controllers import OracleController
from amaze.maze.maze import Maze, MazeClass, rotations

#: Maze-string templates per class; clues, lures and traps of several shapes and values.
TEMPLATES = [
    "U",
    "U_l.3_Lwarning-.4",
    "C1",
    "Cpoint-.5",
    "C1_l.25_L.25",
    "Cstar-.8_l.4_Lwarning-.3_L.2",
    "C1_t.5_T.5",
    "C1_t1_Tforbidden-.4",
    "C1_l.25_L.25_t.5_T.5",
    "C1_Cpoint-.6_l.4_L.25_Lalien-.3_t.5_T.5_Trarrow-.45",
]
#: The oracle's share of the moves, by environment (pure random to pure oracle).
ORACLE_SHARES = np.array([0.0, 0.5, 0.85, 1.0])


def maze_strings(n: int, seed: int) -> list[str]:
    """``n`` random maze strings (class, size 2..30 each way, seed, start corner, ``R``)."""
    rng = np.random.default_rng(seed)
    strings = []
    for k in range(n):
        template = TEMPLATES[k % len(TEMPLATES)]
        width, height = rng.integers(2, 31, size=2)
        corner = ["SW", "SE", "NE", "NW"][rng.integers(4)]
        rotated = "" if rng.random() < 0.75 else "_R"
        strings.append(f"M{rng.integers(10**6)}_{width}x{height}_{corner}{rotated}_{template}")
    return strings


@dataclass
class EngineRecord:
    """What the engine did: its actions and, per step, what it returned (dense arrays)."""

    actions: list = field(default_factory=list)
    observations: list = field(default_factory=list)
    rewards: list = field(default_factory=list)
    terminated: list = field(default_factory=list)
    truncated: list = field(default_factory=list)
    final: list = field(default_factory=list)
    counters: list = field(default_factory=list)  # steps, collisions, backsteps, len, success
    scores: list = field(default_factory=list)  # return, R̄, pretty (float64)

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: np.stack(values) for name, values in vars(self).items()}


def play_engine(mazes: list[Maze], robot: str, steps: int, deadline_factor: float) -> dict:
    """One engine agent per maze, oracle and random moves mixed; every step recorded."""
    n = len(mazes)
    engine = BatchEngine(mazes, robot, n, deadline_factor=deadline_factor, parallel=False)
    oracle = OracleController(robot)
    oracle.bind(engine)
    rng = np.random.default_rng(7)
    share = ORACLE_SHARES[(np.arange(n) + np.arange(n) // 4) % len(ORACLE_SHARES)]
    observations = engine.reset()
    record = EngineRecord()
    record.observations.append(observations)
    for _ in range(steps):
        actions = np.where(rng.random(n) < share, oracle(observations), rng.integers(0, 4, n))
        result = engine.step(actions)
        episodes = result.episodes
        final = np.zeros_like(result.observations)
        counters = np.zeros((n, 5), dtype=np.int64)
        scores = np.zeros((n, 3), dtype=np.float64)
        agents = episodes.agents
        final[agents] = result.final_observations
        counters[agents] = np.stack(
            [
                episodes.steps,
                episodes.collisions,
                episodes.backsteps,
                episodes.path_length,
                episodes.success,
            ],
            axis=1,
        )
        scores[agents] = np.stack(
            [episodes.cumulative_reward, episodes.normalized_rewards(), episodes.pretty_rewards()],
            axis=1,
        )
        for name, value in [
            ("actions", actions),
            ("observations", result.observations),
            ("rewards", result.rewards),
            ("terminated", result.terminated),
            ("truncated", result.truncated),
            ("final", final),
            ("counters", counters),
            ("scores", scores),
        ]:
            getattr(record, name).append(value)
        observations = result.observations
    arrays = record.arrays()
    arrays["first"], arrays["observations"] = arrays["observations"][0], arrays["observations"][1:]
    return arrays


@partial(jax.jit, static_argnums=0)
def play_jax(env, params, actions):
    """The JAX environments replaying ``actions`` (steps, n) in one compiled scan."""
    n = actions.shape[1]
    keys = jax.random.split(jax.random.key(0), n)
    first, state = jax.vmap(env.reset)(keys, params)

    def one_step(state, action):
        obs, state, reward, terminated, truncated, info = jax.vmap(env.step)(
            keys, state, action, params
        )
        counters = jnp.stack(
            [
                info[k].astype(jnp.int32)
                for k in ("steps", "collisions", "backsteps", "len", "success")
            ],
            axis=-1,
        )
        scores = jnp.stack(
            [info[k] for k in ("cumulative_reward", "normalized_reward", "pretty_reward")], axis=-1
        )
        out = (obs, reward, terminated, truncated, info["final_observation"], counters, scores)
        return state, out

    _, outputs = jax.lax.scan(one_step, state, actions)
    names = ("observations", "rewards", "terminated", "truncated", "final", "counters", "scores")
    return first, dict(zip(names, outputs, strict=True))


def near_tie(returns: np.ndarray, length: np.ndarray, deadline_factor: float) -> np.ndarray:
    """Episodes whose pretty reward is within 1e-6 of a tie of its rounding to 3 decimals.

    Computed in float64 from the engine's return: float32 arithmetic may round
    such values the other way (by 0.001).
    """
    worst = RewardScheme(1, 1.0, deadline_factor).minimal_reward  # per unit of l
    r_min = worst * length
    scaled = 1000 * (2.0 * (returns - r_min) / (length - r_min) - 1.0)
    return np.abs(np.abs(scaled - np.floor(scaled)) - 0.5) < 1e-3


def check_scores(engine: dict, jax_out: dict, done: np.ndarray, deadline_factor: float) -> int:
    """Compare the scores of the ended episodes; returns how many were compared.

    JAX's return and R̄ are the float32 nearest the exact rationals (see
    ``amaze.envs.jax.env``). The engine's are float64, computed with their own
    rounding errors: its return is a running sum of inexact rewards (-1.2,
    -1.1...), off the exact value by up to about 1e-13 here (a return of exactly
    0 reads -2.8e-14 there), and R̄ sums four rounded terms. Rounded to float32,
    the two agree but for those errors: the bound is one float32 ulp of the
    engine's value, or 1e-9 where that ulp is smaller (returns near 0).
    """
    ours = jax_out["scores"][done]
    theirs = engine["scores"][done]
    for column in (0, 1):
        rounded = theirs[:, column].astype(np.float32)
        bound = np.maximum(np.spacing(np.abs(rounded)), 1e-9)
        assert np.all(np.abs(ours[:, column] - theirs[:, column]) <= bound), column
    pretty, expected = ours[:, 2], theirs[:, 2].astype(np.float32)
    ties = near_tie(
        theirs[:, 0], engine["counters"][done][:, 3].astype(np.float64), deadline_factor
    )
    np.testing.assert_array_equal(pretty[~ties], expected[~ties])
    assert np.all(np.abs(pretty[ties] - expected[ties]) <= 1.0005e-3)
    return int(done.sum())


def corner(maze: Maze) -> tuple[bool, bool]:
    """Where a maze starts: (east side, north side)."""
    i, j = maze.start
    return (i == maze.width - 1, j == maze.height - 1)


CASES = [
    # robot, base mazes (x 4 rotations), steps, deadline factor, seed of the maze strings
    ("DD", 200, 1500, 4.0, 1),
    ("H5", 200, 600, 2.5, 2),
    ("H11", 200, 600, 1.0, 3),
    ("H15", 200, 800, 4.0, 4),
]


@pytest.mark.parametrize(("robot", "n_mazes", "steps", "deadline_factor", "seed"), CASES)
def test_jax_env_plays_the_engines_episodes(robot, n_mazes, steps, deadline_factor, seed):
    mazes = [Maze.from_string(s) for s in rotations(maze_strings(n_mazes, seed))]
    assert len(mazes) == 4 * n_mazes
    assert {m.maze_class for m in mazes} == {
        MazeClass.TRIVIAL, MazeClass.SIMPLE, MazeClass.LURES, MazeClass.TRAPS, MazeClass.COMPLEX,
    }  # fmt: skip
    assert any(m.unicursive for m in mazes)
    assert len({corner(m) for m in mazes}) == 4
    assert {m.width for m in mazes} >= {2, 30}

    engine = play_engine(mazes, robot, steps, deadline_factor)
    env, params = make_batch(mazes, robot, deadline_factor=deadline_factor)
    first, out = play_jax(env, params, jnp.asarray(engine["actions"], dtype=jnp.int32))
    out = {name: np.asarray(value) for name, value in out.items()}
    squeeze = (lambda a: a) if robot == "DD" else (lambda a: a[..., 0, :, :])

    np.testing.assert_array_equal(squeeze(np.asarray(first)), engine["first"])
    np.testing.assert_array_equal(squeeze(out["observations"]), engine["observations"])
    np.testing.assert_array_equal(out["rewards"], engine["rewards"].astype(np.float32))
    np.testing.assert_array_equal(out["terminated"], engine["terminated"])
    np.testing.assert_array_equal(out["truncated"], engine["truncated"])
    done = engine["terminated"] | engine["truncated"]
    np.testing.assert_array_equal(squeeze(out["final"])[done], engine["final"][done])
    np.testing.assert_array_equal(out["counters"][done], engine["counters"][done])
    ended = check_scores(engine, out, done, deadline_factor)

    # the mix of policies gave every kind of episode
    assert engine["terminated"].sum() > len(mazes) and engine["truncated"].sum() > len(mazes) // 4
    assert engine["counters"][done][:, 1].sum() > 0 and engine["counters"][done][:, 2].sum() > 0
    assert ended > len(mazes)

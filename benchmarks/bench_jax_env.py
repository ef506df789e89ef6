"""Throughput of AMaze as a JAX environment, beside the numba vector env and gymnax's FourRooms.

Env-steps per second with random actions, for ``DD`` and ``H15`` (and continuous
robots, ``--robots CC15``: accelerations uniform in [-1, 1]) at 4, 64 and
4096 environments, on the paper's complex 20x20 mazes
``M<seed>_20x20_C1_l.25_L.25_t.5_T.5`` (16 seeds; environment ``k`` plays maze
``k % 16``, from params stacked with ``amaze.envs.jax.make_batch``, or
``amaze.envs.jax.continuous.make_continuous`` for continuous robots):

* **amaze JAX**: ``jax.vmap(env.step)`` inside one compiled ``lax.scan``, the
  actions drawn in the scan (``jax.random.randint``), a key per environment and
  step split as PureJaxRL does, the observations and a sum of the rewards
  carried so that nothing is compiled away;
* **numba vector env**: ``gymnasium.make_vec("AMaze-v0", ...,
  vectorization_mode="vector_entry_point")`` stepped from Python with actions
  drawn beforehand (``benchmarks/bench_engine.py --target vector``);
* **gymnax FourRooms-misc**: the same compiled scan as ours (its params shared
  by all environments, gymnax's default), as a yardstick of JAX environments.

Each repeat times ``--steps`` steps (by default 2 million env-steps, within
200 to 50,000 steps; the vector env at most 20,000 steps); the median over
``--repeats`` is printed. For the compiled scans, compilation is timed apart
(``jit(...).lower(...).compile()``) and excluded, and one untimed run
precedes the repeats. Targets on a 2-core CPU: ``DD`` at 4096 environments at
least FourRooms' rate in the same run (about 7.5 M/s measured before), and at
least 0.3 M/s at 4 environments.

Usage: ``python benchmarks/bench_jax_env.py [--robots DD H15] [--envs 4 64 4096]
[--repeats 5] [--steps N]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import gymnasium
import gymnax
import jax
import jax.numpy as jnp
import numba
import numpy as np

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.agents.robot import as_robot
from amaze.envs.jax import make_batch
from amaze.envs.jax.continuous import JaxContinuousEnv, make_continuous

MAZE = "M{seed}_20x20_C1_l.25_L.25_t.5_T.5"
N_MAZES = 16
STEP_BUDGET = 2_000_000


def compiled_rollout(env, params, n: int, steps: int, params_axis: int | None) -> Callable:
    """A jitted ``key -> carry``: ``steps`` random steps of ``n`` environments in one scan."""
    reset = jax.vmap(env.reset, in_axes=(0, params_axis))
    step = jax.vmap(env.step, in_axes=(0, 0, 0, params_axis))

    def one_step(carry, _):
        key, state, obs, total = carry
        key, k_action, k_step = jax.random.split(key, 3)
        if isinstance(env, JaxContinuousEnv):
            actions = jax.random.uniform(k_action, (n, 2), minval=-1.0, maxval=1.0)
        else:
            actions = jax.random.randint(k_action, (n,), 0, 4)
        obs, state, reward, _, _, _ = step(jax.random.split(k_step, n), state, actions, params)
        return (key, state, obs, total + reward.sum()), None

    def rollout(key):
        obs, state = reset(jax.random.split(key, n), params)
        carry = (key, state, obs, jnp.float32(0))
        return jax.lax.scan(one_step, carry, None, length=steps)[0]

    return jax.jit(rollout)


def time_jax(env, params, n: int, steps: int, repeats: int, params_axis: int | None):
    """(median env-steps/s, compile seconds) of a compiled rollout."""
    rollout = compiled_rollout(env, params, n, steps, params_axis)
    start = time.perf_counter()
    compiled = rollout.lower(jax.random.key(0)).compile()
    compile_seconds = time.perf_counter() - start
    jax.block_until_ready(compiled(jax.random.key(0)))
    rates = []
    for repeat in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(compiled(jax.random.key(repeat + 1)))
        rates.append(steps * n / (time.perf_counter() - start))
    return statistics.median(rates), compile_seconds


def time_vector_env(robot: str, n: int, steps: int, repeats: int) -> float:
    """Median env-steps/s of AMaze-v0's numba vector env stepped from Python."""
    env = gymnasium.make_vec(
        "AMaze-v0",
        num_envs=n,
        vectorization_mode="vector_entry_point",
        maze=[MAZE.format(seed=s) for s in range(N_MAZES)],
        robot=robot,
    )
    rng = np.random.default_rng(0)
    if as_robot(robot).discrete_outputs:
        actions = rng.integers(0, 4, size=(steps, n), dtype=np.int64)
    else:
        actions = rng.uniform(-1.0, 1.0, size=(steps, n, 2))
    env.reset()
    for t in range(min(steps, 50)):  # numba's first calls, the engine's kernel choice
        env.step(actions[t])
    rates = []
    for _ in range(repeats):
        env.reset()
        step = env.step
        start = time.perf_counter()
        for t in range(steps):
            step(actions[t])
        rates.append(steps * n / (time.perf_counter() - start))
    env.close()
    return statistics.median(rates)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["DD", "H15"])
    parser.add_argument("--envs", nargs="+", type=int, default=[4, 64, 4096])
    parser.add_argument("--steps", type=int, default=0, help="steps per repeat (0: per size)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    device = jax.devices()[0]
    print(
        f"JAX {jax.__version__} on {device.platform} ({device.device_kind}),"
        f" numba threads {numba.get_num_threads()}; {N_MAZES} mazes {MAZE.format(seed='<s>')};"
        f" random actions; median of {args.repeats} repeats, M env-steps/s (compile time)"
    )
    rooms, rooms_params = gymnax.make("FourRooms-misc")
    rooms_rates: dict[int, tuple[float, float]] = {}
    print(f"{'robot':>5} {'envs':>5} {'steps':>6}  {'amaze JAX':>17}  {'numba vector env':>16}"
          f"  {'gymnax FourRooms':>17}")  # fmt: skip
    for robot in args.robots:
        for n in args.envs:
            steps = args.steps or max(200, min(50_000, STEP_BUDGET // n))
            mazes = [MAZE.format(seed=s) for s in range(N_MAZES)]
            if as_robot(robot).discrete_outputs:
                env, params = make_batch(mazes, robot, num_envs=n)
            else:
                env, params = make_continuous(mazes, robot, num_envs=n)
            ours, compile_ours = time_jax(env, params, n, steps, args.repeats, 0)
            vector = time_vector_env(robot, n, min(steps, 20_000), args.repeats)
            if n not in rooms_rates:
                rooms_rates[n] = time_jax(rooms, rooms_params, n, steps, args.repeats, None)
            rate, compile_rooms = rooms_rates[n]
            print(
                f"{robot:>5} {n:>5} {steps:>6}  {ours / 1e6:7.2f} ({compile_ours:4.1f} s)"
                f"  {vector / 1e6:16.2f}  {rate / 1e6:7.2f} ({compile_rooms:4.1f} s)",
                flush=True,
            )


if __name__ == "__main__":
    main()

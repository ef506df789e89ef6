"""PPO in one file, PureJaxRL-style, on AMaze's JAX environment.

Everything that runs during training (the rollout of many environments, GAE,
the clipped PPO update) is one function compiled by ``jax.jit``: the policy
and the maze both live on the accelerator (or the CPU), and Python only starts
it. The network is a plain-JAX actor-critic MLP, the optimiser is optax's Adam.

The environment is :mod:`amaze.envs.jax`: ``make_batch`` compiles mazes into
arrays (``params``), ``env.reset`` / ``env.step`` are pure functions that
``jax.vmap`` runs over a batch of environments, and ``step`` restarts an
ended episode by itself (gymnax's auto-reset), reporting the episode's
figures in ``info``.

The agent trains on 8 mazes of one family (``M4_10x10_C1``: 10x10 mazes with
clues, new seeds), each in its four rotations, then its greedy policy is
scored by the project's evaluation protocol
(:func:`amaze.evaluation.protocol.evaluate`), like every other agent of the
project: on its training mazes, on 32 mazes of the family it never saw, and on
the standard evaluation suite (20x20 mazes, some with lures and traps).

Run it::

    python examples/ppo_purejaxrl.py            # 3 M env steps: about 40 s on 2 CPU cores
    python examples/ppo_purejaxrl.py --tiny     # a few updates: a smoke test

Needs JAX and optax: ``pip install "amaze-evo[jax]" optax``.
"""

from __future__ import annotations

import argparse
import itertools
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from amaze.curriculum.validation import unseen_mazes
from amaze.envs.jax import make_batch
from amaze.evaluation.protocol import evaluate
from amaze.maze import MazeSpec, rotations

# -- settings ------------------------------------------------------------------

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--tiny", action="store_true", help="a few updates only (for the tests)")
parser.add_argument("--maze", default="M4_10x10_C1", help="the family of the mazes to learn")
parser.add_argument("--steps", type=int, default=3_000_000, help="env steps to train for")
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()

NUM_ENVS = 64  # environments stepped together (vmap)
NUM_STEPS = 64  # steps per environment per rollout: a batch of 64 x 64 transitions
TOTAL_STEPS = 4 * NUM_ENVS * NUM_STEPS if args.tiny else args.steps
NUM_UPDATES = TOTAL_STEPS // (NUM_ENVS * NUM_STEPS)
UPDATE_EPOCHS = 4  # passes over each batch
NUM_MINIBATCHES = 4
GAMMA, GAE_LAMBDA = 0.99, 0.95
CLIP_EPS = 0.2
ENT_COEF, VF_COEF = 0.01, 0.5
LR, MAX_GRAD_NORM = 1e-3, 0.5

# -- the environment: 64 environments over 8 mazes x 4 rotations -----------------

# 8 mazes of the family of args.maze: its fields with other seeds (so other walls)
train_mazes = [MazeSpec.from_string(args.maze, seed=100 + i).to_string() for i in range(8)]
played = rotations(train_mazes)  # each maze started from each of its four corners: 32
env, env_params = make_batch(played, robot="DD", num_envs=NUM_ENVS)  # env k: played[k % 32]
n_actions = env.action_space(env_params).n  # 4: east, north, west, south
obs_size = env.observation_shape[0]  # DD robots see 8 floats (walls and signs around them)

# -- the network: an actor-critic MLP in plain JAX -------------------------------


def init_network(key: jax.Array, hidden: int = 64) -> dict:
    """Two separate 64-64 tanh MLPs (actor and critic), orthogonally initialised."""
    sizes = {
        "actor": [obs_size, hidden, hidden, n_actions],
        "critic": [obs_size, hidden, hidden, 1],
    }
    gains = {"actor": 0.01, "critic": 1.0}  # small final layers, as in PureJaxRL
    network = {}
    for name, layer_sizes in sizes.items():
        layers = []
        for i, (n_in, n_out) in enumerate(itertools.pairwise(layer_sizes)):
            key, sub = jax.random.split(key)
            last = i == len(layer_sizes) - 2
            init = jax.nn.initializers.orthogonal(gains[name] if last else np.sqrt(2))
            layers.append({"w": init(sub, (n_in, n_out)), "b": jnp.zeros(n_out)})
        network[name] = layers
    return network


def mlp(layers: list, x: jax.Array) -> jax.Array:
    for layer in layers[:-1]:
        x = jnp.tanh(x @ layer["w"] + layer["b"])
    return x @ layers[-1]["w"] + layers[-1]["b"]


def apply_network(network: dict, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Action logits and state values of a batch of observations."""
    return mlp(network["actor"], obs), mlp(network["critic"], obs)[..., 0]


# -- PPO -------------------------------------------------------------------------


class Transition(NamedTuple):
    obs: jax.Array
    action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    reward: jax.Array
    done: jax.Array
    success: jax.Array  # where done: did the episode reach the goal?


optimizer = optax.chain(optax.clip_by_global_norm(MAX_GRAD_NORM), optax.adam(LR, eps=1e-5))


def ppo_loss(network, batch: Transition, advantages, targets):
    logits, values = apply_network(network, batch.obs)
    log_probs = jax.nn.log_softmax(logits)
    log_prob = jnp.take_along_axis(log_probs, batch.action[:, None], axis=1)[:, 0]
    # the clipped value loss and the clipped surrogate objective of PPO
    clipped = batch.value + jnp.clip(values - batch.value, -CLIP_EPS, CLIP_EPS)
    value_loss = 0.5 * jnp.maximum((values - targets) ** 2, (clipped - targets) ** 2).mean()
    ratio = jnp.exp(log_prob - batch.log_prob)
    advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    surrogate = jnp.minimum(
        ratio * advantages, jnp.clip(ratio, 1 - CLIP_EPS, 1 + CLIP_EPS) * advantages
    )
    entropy = -(jnp.exp(log_probs) * log_probs).sum(-1).mean()
    return -surrogate.mean() + VF_COEF * value_loss - ENT_COEF * entropy


def gae(rollout: Transition, last_value: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Generalised advantage estimates, computed backwards through the rollout.

    An episode that ended (at the goal or at its deadline) does not bootstrap
    from the next observation, which already belongs to the next episode.
    """

    def backwards(carry, t: Transition):
        next_advantage, next_value = carry
        delta = t.reward + GAMMA * next_value * (1 - t.done) - t.value
        advantage = delta + GAMMA * GAE_LAMBDA * (1 - t.done) * next_advantage
        return (advantage, t.value), advantage

    start = (jnp.zeros_like(last_value), last_value)
    _, advantages = jax.lax.scan(backwards, start, rollout, reverse=True)
    return advantages, advantages + rollout.value


def train(key: jax.Array):
    """The whole training run: ``NUM_UPDATES`` x (rollout, GAE, PPO epochs)."""
    key, init_key = jax.random.split(key)
    network = init_network(init_key)
    opt_state = optimizer.init(network)
    reset_keys = jax.random.split(key, NUM_ENVS)
    obs, env_state = jax.vmap(env.reset)(reset_keys, env_params)

    def env_step(carry, _):
        network, env_state, obs, key = carry
        key, action_key, step_key = jax.random.split(key, 3)
        logits, value = apply_network(network, obs)
        action = jax.random.categorical(action_key, logits)
        log_prob = jnp.take_along_axis(jax.nn.log_softmax(logits), action[:, None], 1)[:, 0]
        step_keys = jax.random.split(step_key, NUM_ENVS)
        obs_next, env_state, reward, terminated, truncated, info = jax.vmap(env.step)(
            step_keys, env_state, action, env_params
        )
        done = terminated | truncated
        transition = Transition(obs, action, log_prob, value, reward, done, info["success"])
        return (network, env_state, obs_next, key), transition

    def update(carry, _):
        network, opt_state, env_state, obs, key = carry
        # 1. collect NUM_STEPS steps of NUM_ENVS environments with the current policy
        (_, env_state, obs, key), rollout = jax.lax.scan(
            env_step, (network, env_state, obs, key), None, NUM_STEPS
        )
        _, last_value = apply_network(network, obs)
        advantages, targets = gae(rollout, last_value)

        # 2. a few epochs of minibatch gradient steps on the flattened batch
        def epoch(carry, _):
            network, opt_state, key = carry
            key, perm_key = jax.random.split(key)
            batch_size = NUM_STEPS * NUM_ENVS
            order = jax.random.permutation(perm_key, batch_size)
            flat = jax.tree.map(lambda x: x.reshape(batch_size, *x.shape[2:]), rollout)
            data = (flat, advantages.reshape(-1), targets.reshape(-1))
            minibatches = jax.tree.map(
                lambda x: x[order].reshape(NUM_MINIBATCHES, -1, *x.shape[1:]), data
            )

            def gradient_step(carry, minibatch):
                network, opt_state = carry
                loss, grads = jax.value_and_grad(ppo_loss)(network, *minibatch)
                updates, opt_state = optimizer.update(grads, opt_state)
                return (optax.apply_updates(network, updates), opt_state), loss

            (network, opt_state), losses = jax.lax.scan(
                gradient_step, (network, opt_state), minibatches
            )
            return (network, opt_state, key), losses.mean()

        (network, opt_state, key), losses = jax.lax.scan(
            epoch, (network, opt_state, key), None, UPDATE_EPOCHS
        )
        # what the rollout's ended episodes achieved
        episodes = rollout.done.sum()
        successes = (rollout.done & rollout.success).sum()
        metrics = {"episodes": episodes, "successes": successes, "loss": losses.mean()}
        return (network, opt_state, env_state, obs, key), metrics

    key, loop_key = jax.random.split(key)
    carry = (network, opt_state, env_state, obs, loop_key)
    (network, *_), metrics = jax.lax.scan(update, carry, None, NUM_UPDATES)
    return network, metrics


# -- run it ----------------------------------------------------------------------

print(
    f"PPO on 8 mazes like {args.maze} x 4 rotations: {NUM_UPDATES} updates of"
    f" {NUM_ENVS}x{NUM_STEPS} steps"
)
started = time.perf_counter()
network, metrics = jax.jit(train)(jax.random.key(args.seed))
metrics = jax.tree.map(np.asarray, metrics)  # waits for the computation, then numpy arrays
seconds = time.perf_counter() - started
steps = NUM_UPDATES * NUM_ENVS * NUM_STEPS
print(f"trained {steps:,} env steps in {seconds:.1f} s (compilation included)")

# the training curve: how many episodes ended, and how many at the goal, per fifth of training
for fifth, part in enumerate(np.array_split(np.arange(NUM_UPDATES), 5), start=1):
    ended, successes = metrics["episodes"][part].sum(), metrics["successes"][part].sum()
    if ended:
        print(
            f"  training, fifth {fifth}: {int(ended):6d} episodes, success {successes / ended:.2f}"
        )

# -- score the greedy policy with the project's evaluation protocol --------------

greedy = jax.jit(lambda obs: jnp.argmax(apply_network(network, obs)[0], axis=-1))


def policy(observations: np.ndarray) -> np.ndarray:
    """A policy of :mod:`amaze.evaluation.policy`: observations (n, 8) -> actions (n,)."""
    return np.asarray(greedy(jnp.asarray(observations)))


def show(what: str, report) -> None:
    """One line of an EvaluationReport (R̄: the paper's normalised reward, 1 at best)."""
    line = f"{what}: success rate {report.success_rate:.2f}, mean R̄ {report.normalized_reward:+.3f}"
    if report.input_recognition is not None:
        line += f", input recognition {report.input_recognition:.2f}"
    print(line)


show("training mazes (8 x 4)", evaluate(policy, "DD", train_mazes, rotations=4, inputs=False))
unseen = unseen_mazes(args.maze, seed=args.seed, n=32)  # same family, seeds never trained on
show(
    "unseen mazes of the family (32 x 4)", evaluate(policy, "DD", unseen, rotations=4, inputs=False)
)
# the standard suite: 20x20 mazes with clues, lures and traps; inputs: the input-recognition test
show("standard suite (18 x 4)", evaluate(policy, "DD"))

"""The JAX trainer as a run uses it: seeded, resumable bit for bit, exported to SB3.

* one seed, one result: two trainers of the same seed end in the same state,
  bit for bit; another seed differs;
* save and load: training N steps, saving, loading and training M more gives
  the state of N + M steps in one go, bit for bit (however the steps are cut
  into compiled calls);
* the SB3 zip of :meth:`JaxTrainer.export_sb3` loads with SB3's own
  ``PPO.load`` / ``A2C.load``, and SB3's deterministic actions, action
  probabilities and values are the JAX policy's (and the numpy policy's) on
  observations of the training mazes; the optimizer's state goes along.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

jax = pytest.importorskip("jax")
torch = pytest.importorskip("torch")
sb3 = pytest.importorskip("stable_baselines3")

from rl_baselines import RLConfigError  # noqa: E402
from rl_baselines.jax import JaxTrainer  # noqa: E402
from rl_baselines.vec_env import SB3VecEnv  # noqa: E402

MAZES = ["M1_5x5_C1", "M2_6x6_C1_l.25_L.25", "M3_5x5_C1_t.5_T.5"]
PPO_HPS = {"n_steps": 16, "batch_size": 32, "n_epochs": 2}
ROLLOUT = 16 * 4


def _ppo(seed: int) -> JaxTrainer:
    """A small PPO whose compiled calls cover 2 rollouts (so runs cross calls)."""
    return JaxTrainer("ppo", "DD", MAZES, PPO_HPS, seed=seed, chunk_steps=2 * ROLLOUT)


def _equal_states(a: JaxTrainer, b: JaxTrainer) -> bool:
    x, y = a.state_arrays(), b.state_arrays()
    return x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)


def test_same_seed_same_training() -> None:
    a, b, c = _ppo(1), _ppo(1), _ppo(2)
    stats = [t.learn(3 * ROLLOUT) for t in (a, b, c)]
    assert a.num_timesteps == 3 * ROLLOUT and len(stats[0].loss) == 3
    assert _equal_states(a, b)
    assert np.array_equal(stats[0].loss, stats[1].loss)
    assert not _equal_states(a, c)


def test_save_load_continues_bit_for_bit(tmp_path: Path) -> None:
    whole = _ppo(5)
    whole.learn(8 * ROLLOUT)
    first = _ppo(5)
    first.learn(3 * ROLLOUT)
    first.save(tmp_path / "trainer")
    resumed = JaxTrainer.load(tmp_path / "trainer")
    assert resumed.num_timesteps == 3 * ROLLOUT and _equal_states(resumed, first)
    resumed.learn(5 * ROLLOUT)
    assert _equal_states(resumed, whole)
    assert not _equal_states(first, whole)


def test_load_refuses_other_arrays(tmp_path: Path) -> None:
    trainer = _ppo(0)
    arrays = trainer.state_arrays()
    arrays["params/action_net/bias"] = np.zeros(5, np.float32)
    with pytest.raises(RLConfigError, match="action_net"):
        trainer.load_state_arrays(arrays)
    with pytest.raises(RLConfigError, match="does not exist"):
        JaxTrainer.load(tmp_path / "nothing")


def _observations(robot: str, n: int = 48) -> np.ndarray:
    """Observations of the training mazes under random actions."""
    env = SB3VecEnv(MAZES, robot, 4, seed=0)
    rng = np.random.default_rng(0)
    seen = [env.reset()]
    for _ in range(n // 4 - 1):
        seen.append(env.step(rng.integers(0, 4, 4))[0])
    return np.concatenate(seen)


@pytest.mark.parametrize(
    ("algo", "robot", "hps"),
    [("ppo", "DD", PPO_HPS), ("a2c", "H11", {"n_steps": 5})],
)
def test_export_loads_in_sb3_and_acts_alike(
    tmp_path: Path, algo: str, robot: str, hps: dict
) -> None:
    if algo == "ppo":  # trained, so that the optimizer's state is not empty
        trainer = _ppo(3)
        trainer.learn(4 * ROLLOUT)
    else:  # fresh: compiling the CNN's training would cost seconds, the export is the same
        trainer = JaxTrainer(algo, robot, MAZES, hps, seed=3)
    path = trainer.export_sb3(tmp_path / "agent.zip")
    model = {"ppo": sb3.PPO, "a2c": sb3.A2C}[algo].load(path, device="cpu")
    assert model.num_timesteps == trainer.num_timesteps
    optimizer_state = model.policy.optimizer.state_dict()["state"]
    steps = int(optimizer_state[0]["step"]) if optimizer_state else 0
    assert steps == int(trainer.state.opt_state.step) == (4 if algo == "ppo" else 0) * 4
    obs = _observations(robot)
    expected, _ = model.predict(obs, deterministic=True)
    np.testing.assert_array_equal(np.asarray(trainer.jax_policy()(obs)), expected)
    np.testing.assert_array_equal(trainer.policy()(obs), expected)
    with torch.no_grad():
        tensor = model.policy.obs_to_tensor(obs)[0]
        probs = model.policy.get_distribution(tensor).distribution.probs.numpy()
        values = model.policy.predict_values(tensor).numpy()[:, 0]
    logits, jax_values = trainer.policy().logits_and_values(obs)
    shifted = np.exp(logits - logits.max(axis=1, keepdims=True))
    np.testing.assert_allclose(shifted / shifted.sum(1, keepdims=True), probs, atol=1e-6)
    np.testing.assert_allclose(jax_values, values, rtol=1e-5, atol=1e-6)

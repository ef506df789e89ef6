"""The JAX policy's parameters have SB3's names, shapes and initialisation.

For ``DD`` (MlpPolicy) and a hybrid robot (CnnPolicy with SmallCNN): the
modules and shapes are those of the SB3 model ``amaze-train`` builds, and each
weight, seen as an ``(out, in * k * k)`` matrix, is orthogonal with SB3's gain
(sqrt 2 in the features extractor and the MLPs, 0.01 for the action head, 1
for the value head), every bias zero. (The forward pass is compared with
SB3's in ``test_rollout`` and ``test_trainer``.)
"""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")
pytest.importorskip("stable_baselines3")

from rl_baselines.jax.networks import conv_patches, conv_xla, init_params  # noqa: E402
from rl_baselines.jax.sb3_io import sb3_state_dict  # noqa: E402
from rl_baselines.jax.spec import PolicySpec  # noqa: E402
from rl_baselines.learner import new_sb3_model  # noqa: E402
from rl_baselines.vec_env import SB3VecEnv  # noqa: E402

GAINS = {"action_net": 0.01, "value_net": 1.0}


@pytest.mark.parametrize("robot", ["DD", "H5"])
def test_init_is_sb3s(robot: str) -> None:
    spec = PolicySpec(robot)
    params = init_params(spec, jax.random.key(0))
    model = new_sb3_model("ppo", robot, SB3VecEnv(["M0_5x5_C1"], robot, 4), 0, {})
    sb3 = {k: tuple(v.shape) for k, v in model.policy.state_dict().items()}
    ours = {k: tuple(v.shape) for k, v in sb3_state_dict(spec, params).items()}
    assert ours == sb3
    for module, layer in params.items():
        weight = np.asarray(layer["weight"], np.float64).reshape(layer["weight"].shape[0], -1)
        gain = GAINS.get(module, np.sqrt(2))
        gram = weight @ weight.T if weight.shape[0] <= weight.shape[1] else weight.T @ weight
        np.testing.assert_allclose(gram, gain**2 * np.eye(len(gram)), atol=1e-5, err_msg=module)
        assert not np.any(np.asarray(layer["bias"]))
    other = init_params(spec, jax.random.key(1))
    assert not np.array_equal(other["action_net"]["weight"], params["action_net"]["weight"])


@pytest.mark.parametrize("algo", ["a2c", "ppo"])
def test_defaults_are_sb3s(algo: str) -> None:
    """:data:`SB3_DEFAULTS` are the defaults of SB3's ``A2C.__init__`` / ``PPO.__init__``:
    every argument but those the trainer sets itself (configs are checked against them)."""
    import inspect

    import stable_baselines3

    from rl_baselines.config import _RESERVED
    from rl_baselines.jax.hyperparameters import SB3_DEFAULTS

    signature = inspect.signature(getattr(stable_baselines3, algo.upper()).__init__)
    assert set(SB3_DEFAULTS[algo]) == set(signature.parameters) - _RESERVED - {"self"}
    for name, value in SB3_DEFAULTS[algo].items():
        assert signature.parameters[name].default == value, name


def test_the_cpu_convolution_is_xlas_convolution() -> None:
    """The patch product the CPU uses equals ``lax.conv_general_dilated`` (used elsewhere)."""
    rng = np.random.default_rng(5)
    for channels, side in ((1, 15), (16, 11), (3, 7)):
        weight = rng.normal(size=(8, channels, 3, 3)).astype(np.float32)
        images = rng.random((5, channels, side, side)).astype(np.float32)
        patches = np.asarray(conv_patches(jax.numpy.asarray(weight), jax.numpy.asarray(images)))
        reference = np.asarray(conv_xla(jax.numpy.asarray(weight), jax.numpy.asarray(images)))
        assert patches.shape == (5, 8, side, side)
        np.testing.assert_allclose(patches, reference, rtol=1e-5, atol=1e-5)

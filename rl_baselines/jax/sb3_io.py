"""JAX policies to and from SB3's zips: the weights and the optimizer's state.

Both sides name parameters alike (:mod:`rl_baselines.jax.networks`: a JAX
parameter ``params[module][kind]`` is SB3's ``state_dict()[f"{module}.{kind}"]``,
in torch's layout), so the conversion is a copy:

* :func:`sb3_model` builds the SB3 model the trainer's hyperparameters describe
  (:func:`rl_baselines.learner.new_sb3_model`, so ``MlpPolicy`` or ``CnnPolicy``
  with :class:`~rl_baselines.networks.SmallCNN`, as a run of ``amaze-train``
  would), loads the weights into its policy (the shared CNN under its three
  names: ``features_extractor``, ``pi_features_extractor``,
  ``vf_features_extractor``), the optimizer's moments and step count into its
  torch optimizer (matched by parameter name), and sets ``num_timesteps``;
* :func:`export_sb3` saves it with :meth:`rl_baselines.agent.SB3Agent.save` (the
  zip and the JSON beside it), which :meth:`SB3Agent.load` and
  :func:`~rl_baselines.agent.load_sb3_model` read without unpickling;
* :func:`params_from_sb3` and :func:`opt_state_from_sb3` read an SB3 model's
  weights and optimizer state back into JAX's pytrees; :func:`import_sb3` puts
  them into a trainer.

This module imports torch and SB3 (the rest of :mod:`rl_baselines.jax` does not).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm

from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, load_sb3_model
from rl_baselines.jax.networks import Params
from rl_baselines.jax.optim import AdamState, OptState, RMSpropState
from rl_baselines.jax.spec import PolicySpec
from rl_baselines.learner import new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

#: A :class:`rl_baselines.jax.trainer.JaxTrainer` (not imported: the trainer imports this module).
JaxTrainer = Any

__all__ = [
    "export_sb3",
    "import_sb3",
    "opt_state_from_sb3",
    "params_from_sb3",
    "sb3_model",
    "sb3_state_dict",
]

#: A small maze to build SB3 models with (SB3 needs an environment for the spaces only).
_SPACES_MAZE = "M0_5x5_C1"
#: torch's names of the optimizer state tensors, per JAX state field.
_TORCH_STATE = {"exp_avg": "exp_avg", "exp_avg_sq": "exp_avg_sq", "square_avg": "square_avg"}


def _aliases(spec: PolicySpec, module: str) -> list[str]:
    """SB3's names of a module: the shared CNN appears under three."""
    if spec.images and module.startswith("features_extractor."):
        rest = module.removeprefix("features_extractor.")
        return [module, f"pi_features_extractor.{rest}", f"vf_features_extractor.{rest}"]
    return [module]


def sb3_state_dict(spec: PolicySpec, params: Any) -> dict[str, torch.Tensor]:
    """SB3's policy ``state_dict`` of JAX parameters (copies, float32)."""
    state: dict[str, torch.Tensor] = {}
    for module in spec.layer_shapes():
        for kind in ("weight", "bias"):
            value = torch.tensor(np.array(params[module][kind], np.float32))
            for name in _aliases(spec, module):
                state[f"{name}.{kind}"] = value.clone()
    return state


def _parameter_names(model: BaseAlgorithm) -> list[tuple[str, str]]:
    """``(module, kind)`` of each parameter, in the optimizer's order."""
    return [tuple(name.rsplit(".", 1)) for name, _ in model.policy.named_parameters()]  # type: ignore[misc]


def _load_optimizer(model: BaseAlgorithm, opt_state: OptState) -> None:
    """Put the JAX optimizer state into the model's torch optimizer (moments, step)."""
    step = int(opt_state.step)
    if step == 0:
        return  # torch's state is empty before the first step
    optimizer = model.policy.optimizer
    saved = optimizer.state_dict()
    fields = [f for f in opt_state._fields if f != "step"]
    state = {}
    for index, (module, kind) in enumerate(_parameter_names(model)):
        entry: dict[str, torch.Tensor] = {"step": torch.tensor(float(step))}
        for field in fields:
            moments = getattr(opt_state, field)
            entry[_TORCH_STATE[field]] = torch.tensor(np.array(moments[module][kind], np.float32))
        state[index] = entry
    optimizer.load_state_dict({"state": state, "param_groups": saved["param_groups"]})


def sb3_model(trainer: JaxTrainer, seed: int = 0) -> BaseAlgorithm:
    """The SB3 model of the trainer's algorithm and hyperparameters, with its weights,
    optimizer state and ``num_timesteps``."""
    hp = trainer.static.hp
    spec = trainer.static.spec
    env = SB3VecEnv([_SPACES_MAZE], spec.robot, hp.n_envs, seed=seed)
    model = new_sb3_model(hp.algo, spec.robot, env, seed, hp.sb3_kwargs())
    model.policy.load_state_dict(sb3_state_dict(spec, trainer.state.params), strict=True)
    _load_optimizer(model, trainer.state.opt_state)
    model.num_timesteps = trainer.num_timesteps
    return model


def export_sb3(trainer: JaxTrainer, path: str | os.PathLike, seed: int = 0) -> Path:
    """Save the trainer's policy as an SB3 agent: the zip and its JSON; the zip's path."""
    model = sb3_model(trainer, seed)
    return SB3Agent(model, trainer.static.spec.robot, trainer.static.hp.algo).save(path)


def params_from_sb3(model: BaseAlgorithm, spec: PolicySpec) -> Params:
    """JAX parameters of an SB3 model's policy (its shapes checked against ``spec``)."""
    state = model.policy.state_dict()
    params: Params = {}
    for module, shape in spec.layer_shapes().items():
        layer = {}
        for kind, expected in (("weight", shape), ("bias", shape[:1])):
            name = f"{module}.{kind}"
            if name not in state:
                raise RLConfigError(f"SB3 policy has no parameter {name!r}")
            value = state[name].detach().cpu().numpy().astype(np.float32)
            if value.shape != expected:
                raise RLConfigError(
                    f"SB3 parameter {name!r} is {list(value.shape)}, not {list(expected)}"
                )
            layer[kind] = jnp.asarray(value)
        params[module] = layer
    return params


def opt_state_from_sb3(model: BaseAlgorithm, params: Params, rms_prop: bool) -> OptState:
    """The JAX optimizer state of an SB3 model's torch optimizer (zeros before its first step)."""
    saved = model.policy.optimizer.state_dict()["state"]
    names = _parameter_names(model)
    fields = ("square_avg",) if rms_prop else ("exp_avg", "exp_avg_sq")
    moments: dict[str, Params] = {
        f: {m: dict(layer) for m, layer in params.items()} for f in fields
    }
    step = 0
    for index, (module, kind) in enumerate(names):
        entry = saved.get(index)
        for field in fields:
            if entry is None:
                value = jnp.zeros_like(params[module][kind])
            else:
                value = jnp.asarray(entry[_TORCH_STATE[field]].cpu().numpy().astype(np.float32))
            moments[field][module][kind] = value
        if entry is not None:
            step = int(entry["step"])
    if rms_prop:
        return RMSpropState(jnp.int32(step), moments["square_avg"])
    return AdamState(jnp.int32(step), moments["exp_avg"], moments["exp_avg_sq"])


def import_sb3(trainer: JaxTrainer, source: BaseAlgorithm | str | os.PathLike) -> None:
    """Continue ``trainer`` from an SB3 model (or zip): its weights and optimizer state.

    The model must be of the trainer's algorithm and robot (a zip is read with
    :func:`~rl_baselines.agent.load_sb3_model`, without unpickling); its
    optimizer must be the trainer's (RMSprop or Adam).
    """
    hp, spec = trainer.static.hp, trainer.static.spec
    model = source
    if not isinstance(source, BaseAlgorithm):
        model = load_sb3_model(source, hp.algo, spec.robot)
    rms_prop = hp.algo == "a2c" and hp.use_rms_prop
    optimizer = type(model.policy.optimizer).__name__
    if optimizer != ("RMSprop" if rms_prop else "Adam"):
        raise RLConfigError(
            f"SB3 model uses {optimizer}, the trainer {'RMSprop' if rms_prop else 'Adam'}"
        )
    params = params_from_sb3(model, spec)
    opt_state = opt_state_from_sb3(model, params, rms_prop)
    trainer.state = trainer.state._replace(params=params, opt_state=opt_state)

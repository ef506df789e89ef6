"""A trained SB3 model as a policy of the shared protocol (:mod:`amaze.evaluation.policy`).

:class:`SB3Agent` maps a batch of observations in the ``AMaze-v0`` format to a
batch of actions with ``model.predict(obs, deterministic=True)``, so SB3 agents
go through the same evaluation protocol (:func:`amaze.evaluation.protocol.evaluate`) as
evolved ones.

Files: ``save(path)`` writes SB3's zip at ``path`` (``.zip`` is appended when
missing) and a JSON file beside it (same stem, ``.json``) with the robot string
and the algorithm, which :meth:`SB3Agent.load` needs to rebuild the model.

**Loading a file as data** (:func:`load_sb3_model`, used by
:meth:`SB3Agent.load` and by the trainer's resume). SB3's zip holds a ``data``
entry, a JSON object of the model's attributes, some of them cloudpickled
objects (a dict with a ``":serialized:"`` key: the policy class, the spaces,
the schedules...), and ``.pth`` entries of tensors. SB3's own ``load``
unpickles every such value (which runs whatever code the file says), copies
every key onto the model, and hands a stored ``env`` string to ``gym.make``
(which imports the module it names). Here SB3 reads no value of ``data``
itself: every key must be one A2C or PPO writes (:data:`_DATA`), and each
value is checked for its type and bounds, or rebuilt from what we know (the
robot's spaces and policy class, the constant schedules from the numbers
stored beside the pickles, the classes of ``policy_kwargs`` from a fixed
list), and handed to SB3 as ``custom_objects``; any other key or entry
refuses the file, naming it. Entry sizes, network sizes and the rollout's
size are bounded before anything is inflated or built. The ``.pth`` entries
are read with ``torch.load(..., weights_only=True)`` (tensors and plain
containers only), here before SB3 reads them the same way. Any unreadable,
malformed, hostile or inconsistent file raises
:class:`~rl_baselines.RLConfigError` naming it.
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from stable_baselines3 import A2C, PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.torch_layers import FlattenExtractor, NatureCNN
from stable_baselines3.common.type_aliases import GymEnv
from stable_baselines3.common.utils import FloatSchedule
from torch import nn

from amaze.agents.robot import Robot, as_robot
from amaze.archives import read_entry, zip_entries
from amaze.envs.gym_env import action_space, observation_space
from amaze.errors import AmazeError, one_line
from rl_baselines import RLConfigError
from rl_baselines.networks import SmallCNN
from rl_baselines.sb3_file import (
    MAX_TENSOR_FILE_BYTES,
    METADATA_FORMAT,
    REBUILD,
    agent_paths,
    checked_data,
    read_metadata,
    read_model_file,
)

__all__ = ["ALGORITHMS", "SB3Agent", "algorithm_class", "load_sb3_model"]

#: The SB3 algorithms of the paper's RL baselines, by lowercase name.
ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"a2c": A2C, "ppo": PPO}


def algorithm_class(name: str) -> type[BaseAlgorithm]:
    """The SB3 class of algorithm ``name`` (``a2c`` or ``ppo``)."""
    try:
        return ALGORITHMS[str(name).lower()]
    except KeyError:
        raise RLConfigError(
            f"unknown algorithm {name!r} (choose from {', '.join(ALGORITHMS)})"
        ) from None


# -----------------------------------------------------------------------------
# Building the model from the checked file

#: The classes a ``policy_kwargs`` value may name, by the name SB3 stores
#: (:data:`rl_baselines.sb3_file.POLICY_KWARGS_CLASS_NAMES`).
_POLICY_KWARGS_CLASSES: dict[str, type] = {
    str(cls): cls
    for cls in (
        SmallCNN,
        FlattenExtractor,
        NatureCNN,
        torch.optim.Adam,
        torch.optim.AdamW,
        torch.optim.RMSprop,
        torch.optim.SGD,
        nn.Tanh,
        nn.ReLU,
        nn.ELU,
        nn.LeakyReLU,
        nn.Sigmoid,
        nn.GELU,
        nn.SiLU,
    )
}


def _custom_objects(
    data: Mapping[str, Any], algo: str, robot: Robot, given: Mapping[str, Any], source: str
) -> dict[str, Any]:
    """SB3's ``custom_objects`` for every key of ``data``: SB3 itself reads none of them.

    The values are :func:`~rl_baselines.sb3_file.checked_data`'s; the policy
    class and the spaces come from the robot, the schedule and the rollout
    buffer from SB3's classes, and the classes of ``policy_kwargs`` from
    :data:`_POLICY_KWARGS_CLASSES`.
    """
    custom = checked_data(data, algo, robot, given, source)
    policy = "MlpPolicy" if robot.discrete_inputs else "CnnPolicy"
    custom["policy_class"] = ALGORITHMS[algo].policy_aliases[policy]
    custom["observation_space"] = observation_space(robot)
    custom["action_space"] = action_space(robot)
    if custom.get("lr_schedule") == REBUILD:
        custom["lr_schedule"] = FloatSchedule(custom["learning_rate"])
    if custom.get("rollout_buffer_class") == REBUILD:
        custom["rollout_buffer_class"] = RolloutBuffer
    kwargs = custom.get("policy_kwargs")
    if isinstance(kwargs, dict):
        custom["policy_kwargs"] = {
            name: _POLICY_KWARGS_CLASSES.get(value, value) if isinstance(value, str) else value
            for name, value in kwargs.items()
        }
    return custom


def _check_tensor_entries(raw: bytes, source: str) -> None:
    """Every ``.pth`` entry of the zip (sizes already bounded) holds plain tensors."""
    with zip_entries(raw, source, RLConfigError) as archive:
        for name in archive.namelist():
            if name.endswith(".pth"):
                _check_tensor_file(read_entry(archive, name, source, RLConfigError), name, source)


def _check_tensor_file(content: bytes, name: str, source: str) -> None:
    """A ``.pth`` entry (itself a zip) must hold plain tensors of bounded size."""
    where = f"{source}: its entry {name!r}"
    with zip_entries(
        content,
        where,
        RLConfigError,
        max_entry_bytes=MAX_TENSOR_FILE_BYTES,
        max_total_bytes=MAX_TENSOR_FILE_BYTES,
        kind="tensor file (.pth)",
    ):
        pass
    try:
        torch.load(io.BytesIO(content), map_location="cpu", weights_only=True)
    except Exception as error:
        raise RLConfigError(
            f"{where} is not a tensor file readable without unpickling objects ({one_line(error)})"
        ) from None


def load_sb3_model(
    path: str | os.PathLike,
    algo: str,
    robot: Robot | str,
    *,
    env: GymEnv | None = None,
    device: torch.device | str = "cpu",
    **kwargs: Any,
) -> BaseAlgorithm:
    """The SB3 model saved at ``path`` (``algo``, for ``robot``), loaded as data.

    SB3's own ``load`` would unpickle the pickled values of the zip's ``data``
    entry, copy every key onto the model and hand a stored ``env`` to
    ``gym.make`` (see the module docstring). Here every key of ``data`` goes
    through :func:`~rl_baselines.sb3_file.checked_data` (an allow-list of the
    keys A2C and PPO write, with their types and bounds) and reaches SB3 as a
    ``custom_objects`` value: the policy class and the spaces from ``robot``,
    the policy's keyword arguments from their JSON copy (classes from a fixed
    list), the schedules from the stored constants, training state that SB3
    rebuilds as nothing. ``env``, ``device`` and ``kwargs`` go to SB3's
    ``load`` (``kwargs`` set attributes of the model, e.g. ``tensorboard_log``).
    The optimizer's state is loaded too, so training can continue.

    Raises :class:`~rl_baselines.RLConfigError` naming the file when it is
    missing, not a zip, has no ``data``, holds a key or value that is refused,
    has an entry SB3 does not write or a ``.pth`` entry that is not plain
    tensors, declares more than the bounds, or does not fit the algorithm,
    the robot or ``env``.
    """
    path = Path(path)
    source = f"SB3 model '{path}'"
    try:
        algo_class = algorithm_class(algo)
        robot = as_robot(robot)
    except AmazeError as error:
        raise RLConfigError(f"{source}: {error}") from None
    name = str(algo).lower()
    raw, data = read_model_file(path, source)
    custom = _custom_objects(data, name, robot, kwargs, source)
    _check_tensor_entries(raw, source)
    try:
        return algo_class.load(
            io.BytesIO(raw), env=env, device=device, custom_objects=custom, **kwargs
        )
    except Exception as error:
        raise RLConfigError(
            f"{source} cannot be loaded by {name.upper()} for {robot.to_string()} robots:"
            f" {one_line(error)}"
        ) from None


# -----------------------------------------------------------------------------
# The agent


class SB3Agent:
    """A trained SB3 model acting deterministically for ``robot``."""

    def __init__(self, model: BaseAlgorithm, robot: Robot | str, algo: str | None = None) -> None:
        self.model = model
        self.robot = as_robot(robot)
        self.algo = (algo or type(model).__name__).lower()

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions for a batch of observations."""
        actions, _ = self.model.predict(np.asarray(observations), deterministic=True)
        actions = np.asarray(actions)
        if self.robot.discrete_outputs:
            return actions.reshape(-1).astype(np.int64)
        return actions.reshape(-1, 2).astype(np.float64)

    def metadata(self) -> dict[str, Any]:
        """What :meth:`load` needs besides the zip."""
        return {"robot": self.robot.to_string(), "algo": self.algo, "format": METADATA_FORMAT}

    def save(self, path: str | os.PathLike) -> Path:
        """Write the SB3 zip and its JSON metadata atomically; return the zip's path."""
        zip_path, json_path = agent_paths(path)
        zip_path.parent.mkdir(parents=True, exist_ok=True)
        tmp_zip = zip_path.with_name(f".{zip_path.stem}.tmp.zip")
        self.model.save(tmp_zip)
        tmp_json = json_path.with_name(f".{json_path.name}.tmp")
        tmp_json.write_text(json.dumps(self.metadata(), indent=2) + "\n")
        os.replace(tmp_zip, zip_path)
        os.replace(tmp_json, json_path)
        return zip_path

    @classmethod
    def load(cls, path: str | os.PathLike, device: str = "cpu") -> SB3Agent:
        """Load an agent written by :meth:`save` (or a zip SB3's ``save`` wrote), as data.

        Args:
            path: the agent's zip (``.zip`` appended when missing); the JSON
                file beside it gives the robot and the algorithm, which a zip
                without it gives itself (:func:`rl_baselines.sb3_file.stored_metadata`).
            device: torch's device for the model.

        Returns:
            The agent, a policy of the shared protocol (``agent(observations)``).

        Raises:
            RLConfigError: the file is missing, unreadable, malformed or hostile
                (:func:`load_sb3_model`), named in the message.
        """
        zip_path, json_path = agent_paths(path)
        algo, robot = read_metadata(zip_path, json_path)
        return cls(load_sb3_model(zip_path, algo, robot, device=device), robot, algo)

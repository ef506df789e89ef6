"""A trained SB3 model as a policy of the shared protocol (:mod:`amaze.evaluation.policy`).

:class:`SB3Agent` maps a batch of observations in the ``AMaze-v0`` format to a
batch of actions with ``model.predict(obs, deterministic=True)``, so SB3 agents
go through the same evaluation protocol (:func:`amaze.evaluation.protocol.evaluate`) as
evolved ones.

Files: ``save(path)`` writes SB3's zip at ``path`` (``.zip`` is appended when
missing) and a JSON file beside it (same stem, ``.json``) with the robot string
and the algorithm, which :meth:`SB3Agent.load` needs to rebuild the model.

**Loading without unpickling** (:func:`load_sb3_model`, used by
:meth:`SB3Agent.load` and by the trainer's resume). SB3's zip holds a ``data``
entry, a JSON object some of whose values are cloudpickled objects (a dict with
a ``":serialized:"`` key: the policy class, the spaces, the schedules...), and
``.pth`` entries of tensors. SB3's own ``load`` unpickles every such value, and
unpickling runs whatever code the file says. Here none of them is unpickled:
each is replaced (SB3's ``custom_objects``) by an object built from what we know
(the robot's spaces and policy class, the constant schedules from the numbers
stored beside the pickles, the classes of ``policy_kwargs`` from a fixed list)
or the file is refused, naming the entry. The ``.pth`` entries are read with
``torch.load(..., weights_only=True)`` (tensors and plain containers only),
here before SB3 reads them the same way. The whole file is read once and SB3
loads those same bytes. Any unreadable, malformed or inconsistent file raises
:class:`~rl_baselines.RLConfigError` naming it.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import zipfile
from collections.abc import Callable, Mapping
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
from amaze.envs.gym_env import action_space, observation_space
from amaze.errors import AmazeError, one_line
from rl_baselines import RLConfigError
from rl_baselines.networks import SmallCNN

__all__ = ["ALGORITHMS", "SB3Agent", "algorithm_class", "load_sb3_model"]

#: The SB3 algorithms of the paper's RL baselines, by lowercase name.
ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"a2c": A2C, "ppo": PPO}

#: What :meth:`SB3Agent.save` writes in the JSON file beside the zip (``format``).
METADATA_FORMAT = "sb3-zip"


def algorithm_class(name: str) -> type[BaseAlgorithm]:
    """The SB3 class of algorithm ``name`` (``a2c`` or ``ppo``)."""
    try:
        return ALGORITHMS[str(name).lower()]
    except KeyError:
        raise RLConfigError(
            f"unknown algorithm {name!r} (choose from {', '.join(ALGORITHMS)})"
        ) from None


def _paths(path: str | os.PathLike) -> tuple[Path, Path]:
    zip_path = Path(path)
    if zip_path.suffix != ".zip":
        zip_path = zip_path.with_name(zip_path.name + ".zip")
    return zip_path, zip_path.with_suffix(".json")


# -----------------------------------------------------------------------------
# The pickled values of SB3's ``data`` entry, rebuilt without unpickling

#: The classes a ``policy_kwargs`` value may name (SB3 stores ``str(cls)`` beside
#: the pickle): our CNN, SB3's extractors, torch's usual optimizers and activations.
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

#: SB3's description of a constant schedule (``FloatSchedule.value_schedule``).
_CONSTANT_SCHEDULE = re.compile(r"ConstantSchedule\(val=([^()]*)\)")


def _pickled(value: Any) -> bool:
    """Whether SB3's ``load`` would unpickle this value of ``data`` (its own test)."""
    return isinstance(value, dict) and ":serialized:" in value


def _stored_number(data: Mapping[str, Any], key: str, source: str) -> float:
    value = data.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise RLConfigError(f"{source}: {key} {value!r} in its data is not a finite number")
    return float(value)


def _lr_schedule(key: str, entry: dict, data: Mapping[str, Any], source: str) -> Any:
    """SB3 rebuilds the schedule from ``learning_rate`` anyway: the same, from the number."""
    return FloatSchedule(_stored_number(data, "learning_rate", source))


def _clip_range(key: str, entry: dict, data: Mapping[str, Any], source: str) -> float:
    """PPO's clip range: the constant of the ``ConstantSchedule`` described beside the pickle."""
    description = entry.get("value_schedule")
    match = _CONSTANT_SCHEDULE.fullmatch(description) if isinstance(description, str) else None
    try:
        value = float(match.group(1)) if match else math.nan
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise RLConfigError(
            f"{source}: data entry {key!r} is not a constant schedule ({description!r});"
            " it is refused rather than unpickled"
        )
    return value


def _policy_kwargs(key: str, entry: dict, data: Mapping[str, Any], source: str) -> dict:
    """The policy's keyword arguments from the JSON copy of their items SB3 stores.

    JSON values are taken as they are; a value SB3 wrote as ``str(obj)`` must be
    one of the classes of :data:`_POLICY_KWARGS_CLASSES`.
    """
    if entry.get(":type:") != str(dict):
        raise RLConfigError(f"{source}: data entry {key!r} is not a dict ({entry.get(':type:')!r})")
    kwargs: dict[str, Any] = {}
    for name, value in entry.items():
        if name in (":type:", ":serialized:"):
            continue
        if isinstance(value, str) and value.startswith("<"):
            if value not in _POLICY_KWARGS_CLASSES:
                raise RLConfigError(
                    f"{source}: {key}[{name!r}] is {value}, not a class this loader rebuilds"
                    " without unpickling"
                )
            value = _POLICY_KWARGS_CLASSES[value]
        kwargs[name] = value
    return kwargs


def _nothing(key: str, entry: dict, data: Mapping[str, Any], source: str) -> None:
    """Training state that SB3 rebuilds when it is missing (``learn`` resets the env)."""
    return None


def _rollout_buffer(key: str, entry: dict, data: Mapping[str, Any], source: str) -> type:
    """The rollout buffer of Box observations (SB3's own choice for them)."""
    return RolloutBuffer


_Rebuild = Callable[[str, dict, Mapping[str, Any], str], Any]

#: The pickled ``data`` values rebuilt without unpickling, for every algorithm...
_REBUILT: dict[str, _Rebuild] = {
    "policy_kwargs": _policy_kwargs,
    "lr_schedule": _lr_schedule,
    "rollout_buffer_class": _rollout_buffer,
    "_last_obs": _nothing,
    "_last_episode_starts": _nothing,
    "_last_original_obs": _nothing,
    "ep_info_buffer": _nothing,
    "ep_success_buffer": _nothing,
}
#: ... and for one algorithm only.
_REBUILT_BY_ALGORITHM: dict[str, dict[str, _Rebuild]] = {
    "a2c": {},
    "ppo": {"clip_range": _clip_range, "clip_range_vf": _clip_range},
}


def _stored_shape(entry: Any) -> tuple[int, ...] | None:
    """The shape SB3 wrote beside a pickled space (``_shape``), if readable."""
    shape = entry.get("_shape") if isinstance(entry, dict) else None
    if isinstance(shape, list) and all(type(n) is int for n in shape):
        return tuple(shape)
    return None


def _custom_objects(
    data: Mapping[str, Any], algo: str, robot: Robot, given: Mapping[str, Any], source: str
) -> dict[str, Any]:
    """A replacement for every pickled value of ``data`` (SB3's ``custom_objects``).

    The policy class and the spaces always come from the robot (whatever the
    file holds); a value the caller passes in ``given`` (keyword arguments of
    the load) replaces the stored one; the others are rebuilt by
    :data:`_REBUILT`. Any other pickled value refuses the file.
    """
    policy = "MlpPolicy" if robot.discrete_inputs else "CnnPolicy"
    custom: dict[str, Any] = {
        "policy_class": ALGORITHMS[algo].policy_aliases[policy],
        "observation_space": observation_space(robot),
        "action_space": action_space(robot),
    }
    for key in ("observation_space", "action_space"):
        stored, expected = _stored_shape(data.get(key)), tuple(custom[key].shape)
        if stored is not None and stored != expected:
            raise RLConfigError(
                f"{source}: its {key} has shape {stored}, robot {robot.to_string()}'s has"
                f" {expected}: the model was trained for another robot"
            )
    stored = "ppo" if "clip_range" in data else "a2c"  # PPO's own hyperparameter
    if stored != algo:
        raise RLConfigError(f"{source} was saved by {stored.upper()}, not {algo.upper()}")
    rebuilt = {**_REBUILT, **_REBUILT_BY_ALGORITHM[algo]}
    for key, entry in data.items():
        if key in custom or not _pickled(entry):
            continue
        if key in given:
            custom[key] = given[key]
        elif key in rebuilt:
            custom[key] = rebuilt[key](key, entry, data, source)
        else:
            kind = entry.get(":type:")
            raise RLConfigError(
                f"{source}: data entry {key!r} is a pickled object ({kind}) that this loader"
                f" does not rebuild for {algo}; the file is refused rather than unpickled"
            )
    return custom


def _read_model_file(path: Path, source: str) -> tuple[bytes, dict[str, Any]]:
    """The file's bytes and its ``data`` object, every ``.pth`` entry checked weights-only."""
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise RLConfigError(f"{source} cannot be read: {error.strerror or error}") from None
    # The parsers (zipfile, json, torch, SB3) raise all kinds of errors on a malformed
    # file: each one becomes an RLConfigError naming the file and what was read.
    try:
        archive = zipfile.ZipFile(io.BytesIO(raw))
    except Exception as error:
        raise RLConfigError(f"{source} is not a zip archive ({one_line(error)})") from None
    with archive:
        names = archive.namelist()
        if "data" not in names:
            raise RLConfigError(
                f"{source} has no 'data' entry (it is truncated, or not a model saved by SB3)"
            )
        try:
            data = json.loads(archive.read("data").decode("utf-8"))
        except Exception as error:
            raise RLConfigError(
                f"{source}: its 'data' entry is not readable JSON ({one_line(error)})"
            ) from None
        if not isinstance(data, dict):
            raise RLConfigError(f"{source}: its 'data' entry is not a JSON object")
        for name in names:
            if os.path.splitext(name)[1] != ".pth":
                continue
            try:
                torch.load(io.BytesIO(archive.read(name)), map_location="cpu", weights_only=True)
            except Exception as error:
                raise RLConfigError(
                    f"{source}: its entry {name!r} is not a tensor file readable without"
                    f" unpickling objects ({one_line(error)})"
                ) from None
    return raw, data


def load_sb3_model(
    path: str | os.PathLike,
    algo: str,
    robot: Robot | str,
    *,
    env: GymEnv | None = None,
    device: torch.device | str = "cpu",
    **kwargs: Any,
) -> BaseAlgorithm:
    """The SB3 model saved at ``path`` (``algo``, for ``robot``), loaded without unpickling.

    SB3's ``load`` would unpickle the pickled values of the zip's ``data``
    entry, which can run arbitrary code (see the module docstring): each one
    is rebuilt instead (the policy class and the spaces from ``robot``; the
    policy's keyword arguments from their JSON copy, classes from a fixed
    list; the learning-rate and clip-range schedules from the constants
    stored in JSON; training state that SB3 rebuilds, such as the last
    observations and the episode-statistics buffers, as nothing), and a file
    with any other pickled value is refused. ``env``, ``device`` and
    ``kwargs`` go to SB3's ``load`` (``kwargs`` set attributes of the model,
    e.g. ``tensorboard_log``; one named like a pickled value replaces it).
    The optimizer's state is loaded too, so training can continue.

    Raises :class:`~rl_baselines.RLConfigError` naming the file when it is
    missing, not a zip, has no ``data``, holds a value that cannot be rebuilt,
    has a ``.pth`` entry that is not plain tensors, or does not fit the
    algorithm, the robot or ``env``.
    """
    path = Path(path)
    source = f"SB3 model '{path}'"
    try:
        algo_class = algorithm_class(algo)
        robot = as_robot(robot)
    except AmazeError as error:
        raise RLConfigError(f"{source}: {error}") from None
    name = str(algo).lower()
    raw, data = _read_model_file(path, source)
    custom = _custom_objects(data, name, robot, kwargs, source)
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


def _read_metadata(zip_path: Path, json_path: Path) -> tuple[str, Robot]:
    """The algorithm and the robot of the JSON file beside an agent's zip, checked."""
    source = f"SB3 agent '{zip_path}'"
    if not zip_path.is_file():
        what = "is not a file" if zip_path.exists() else "does not exist"
        raise RLConfigError(f"agent file '{zip_path}' {what}")
    if not json_path.is_file():
        raise RLConfigError(
            f"{source}: its metadata file '{json_path}' does not exist"
            " (SB3Agent.save writes it beside the zip, with the robot and the algorithm)"
        )
    try:
        meta = json.loads(json_path.read_text(encoding="utf-8"))
    except OSError as error:
        raise RLConfigError(
            f"{source}: its metadata file '{json_path}' cannot be read: {error.strerror or error}"
        ) from None
    except (ValueError, RecursionError) as error:  # JSON, UTF-8 and number errors
        raise RLConfigError(
            f"{source}: its metadata file '{json_path}' is not valid JSON ({one_line(error)})"
        ) from None
    if not isinstance(meta, dict):
        raise RLConfigError(f"{source}: its metadata file '{json_path}' is not a JSON object")
    fmt = meta.get("format", METADATA_FORMAT)
    if fmt != METADATA_FORMAT:
        raise RLConfigError(
            f"{source}: metadata 'format' {fmt!r} is not {METADATA_FORMAT!r} ('{json_path}')"
        )
    algo = meta.get("algo")
    if not isinstance(algo, str) or algo.lower() not in ALGORITHMS:
        raise RLConfigError(
            f"{source}: metadata 'algo' {algo!r} is not one of {', '.join(ALGORITHMS)}"
            f" ('{json_path}')"
        )
    try:
        robot = as_robot(meta.get("robot"))
    except AmazeError as error:
        raise RLConfigError(f"{source}: metadata 'robot': {error} ('{json_path}')") from None
    return algo.lower(), robot


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
        zip_path, json_path = _paths(path)
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
        """Load an agent written by :meth:`save`, without unpickling (:func:`load_sb3_model`).

        A missing, unreadable or malformed zip or metadata file raises
        :class:`~rl_baselines.RLConfigError` naming it.
        """
        zip_path, json_path = _paths(path)
        algo, robot = _read_metadata(zip_path, json_path)
        return cls(load_sb3_model(zip_path, algo, robot, device=device), robot, algo)

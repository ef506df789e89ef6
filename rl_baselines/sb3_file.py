"""An SB3 agent file read as data, before torch or stable-baselines3 is imported.

An SB3 agent is a zip (SB3's ``save``) and a JSON file beside it (the robot
and the algorithm, written by :meth:`rl_baselines.agent.SB3Agent.save`). This
module reads and checks both without torch: the metadata
(:func:`read_metadata`), the zip's entries and their declared sizes, and the
zip's ``data`` entry through an allow-list (:func:`checked_data`: every key
one that A2C or PPO writes, every value of its type and within its bounds,
network and rollout sizes included). :mod:`rl_baselines.agent` builds the
model only from what passed; :func:`rl_baselines.agent_loader.load_agent`
(the ``zip`` loader of the ``amaze.agent_loaders`` entry points) refuses a
hostile file through this module before torch is imported, so that a refusal
costs a fraction of a second and no more memory than the command itself.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from amaze.agents.robot import Robot, as_robot
from amaze.archives import read_entry, zip_entries
from amaze.envs.gym_env import action_space, observation_space
from amaze.errors import AmazeError, one_line
from amaze.validation import (
    MAX_LAYER_WIDTH,
    MAX_ROLLOUT_SAMPLES,
    check_integer,
    check_layer_widths,
    check_number,
    check_rollout_size,
    parse_json,
)
from rl_baselines import RLConfigError

__all__ = [
    "ALGORITHM_NAMES",
    "METADATA_FORMAT",
    "POLICY_KWARGS_CLASS_NAMES",
    "REBUILD",
    "agent_paths",
    "checked_data",
    "read_metadata",
    "read_model_file",
]

#: The algorithms of SB3 agents (:data:`rl_baselines.agent.ALGORITHMS`, by name).
ALGORITHM_NAMES = ("a2c", "ppo")
#: What :meth:`~rl_baselines.agent.SB3Agent.save` writes in the JSON file beside the zip.
METADATA_FORMAT = "sb3-zip"


def agent_paths(path: str | os.PathLike) -> tuple[Path, Path]:
    """The agent's zip (``.zip`` appended when missing) and its metadata file beside it."""
    zip_path = Path(path)
    if zip_path.suffix != ".zip":
        zip_path = zip_path.with_name(zip_path.name + ".zip")
    return zip_path, zip_path.with_suffix(".json")


def read_metadata(zip_path: Path, json_path: Path) -> tuple[str, Robot]:
    """The algorithm and the robot of an agent's zip: from the JSON file beside it, checked,
    or (a zip saved by SB3 itself, ``model.save``) from the zip (:func:`stored_metadata`)."""
    source = f"SB3 agent '{zip_path}'"
    if not zip_path.is_file():
        what = "is not a file" if zip_path.exists() else "does not exist"
        raise RLConfigError(f"agent file '{zip_path}' {what}")
    if not json_path.exists():
        return stored_metadata(zip_path)
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
    if not isinstance(algo, str) or algo.lower() not in ALGORITHM_NAMES:
        raise RLConfigError(
            f"{source}: metadata 'algo' {algo!r} is not one of {', '.join(ALGORITHM_NAMES)}"
            f" ('{json_path}')"
        )
    try:
        robot = as_robot(meta.get("robot"))
    except AmazeError as error:
        raise RLConfigError(f"{source}: metadata 'robot': {error} ('{json_path}')") from None
    return algo.lower(), robot


def stored_metadata(zip_path: Path) -> tuple[str, Robot]:
    """The algorithm and the robot of a zip that SB3 saved itself, read from its ``data``.

    PPO alone stores ``clip_range``; the robot follows from the spaces SB3
    stores: 8 inputs (DD) or a ``(1, v, v)`` image (vision ``v``), and 4
    discrete actions or 2 accelerations. A zip whose spaces are no robot's
    raises :class:`~rl_baselines.RLConfigError` naming it.
    """
    source = f"SB3 model '{zip_path}'"
    _, data = read_model_file(zip_path, source)
    algo = "ppo" if "clip_range" in data else "a2c"
    inputs = _stored_shape(data.get("observation_space"))
    actions = data.get("action_space")
    kind = actions.get(":type:", "") if isinstance(actions, dict) else ""
    outputs = "D" if "Discrete" in str(kind) else "C" if "Box" in str(kind) else None
    if inputs == (8,) and outputs is not None:
        name = f"D{outputs}"
    elif inputs is not None and len(inputs) == 3 and inputs[0] == 1 and inputs[1] == inputs[2]:
        name = f"C{outputs}{inputs[1]}" if outputs is not None else ""
    else:
        name = ""
    try:
        return algo, as_robot(name)
    except AmazeError:
        raise RLConfigError(
            f"{source} has no metadata file beside it, and its spaces (inputs {inputs},"
            f" actions {kind or None}) are no robot's: save it with SB3Agent.save, which"
            " writes the robot"
        ) from None


#: The classes a ``policy_kwargs`` value may name, as SB3 stores them (``str(cls)``
#: beside the pickle): our CNN, SB3's extractors, torch's usual optimizers and
#: activations. :mod:`rl_baselines.agent` maps each to its class (a test checks
#: that both lists agree).
POLICY_KWARGS_CLASS_NAMES = frozenset(
    {
        "<class 'rl_baselines.networks.SmallCNN'>",
        "<class 'stable_baselines3.common.torch_layers.FlattenExtractor'>",
        "<class 'stable_baselines3.common.torch_layers.NatureCNN'>",
        "<class 'torch.optim.adam.Adam'>",
        "<class 'torch.optim.adamw.AdamW'>",
        "<class 'torch.optim.rmsprop.RMSprop'>",
        "<class 'torch.optim.sgd.SGD'>",
        "<class 'torch.nn.modules.activation.Tanh'>",
        "<class 'torch.nn.modules.activation.ReLU'>",
        "<class 'torch.nn.modules.activation.ELU'>",
        "<class 'torch.nn.modules.activation.LeakyReLU'>",
        "<class 'torch.nn.modules.activation.Sigmoid'>",
        "<class 'torch.nn.modules.activation.GELU'>",
        "<class 'torch.nn.modules.activation.SiLU'>",
    }
)
#: The value :func:`checked_data` gives the pickled objects that
#: :mod:`rl_baselines.agent` rebuilds with SB3's classes (the learning-rate
#: schedule from ``learning_rate``, the rollout buffer of Box observations).
REBUILD = "<rebuilt from the checked numbers>"

#: SB3's description of a constant schedule (``FloatSchedule.value_schedule``).
_CONSTANT_SCHEDULE = re.compile(r"ConstantSchedule\(val=([^()]*)\)")

#: Bounds on the sizes a file may ask for, checked before the model is built:
#: SB3 allocates its rollout buffer (``n_steps x n_envs`` observations) and the
#: networks when it builds the model. Far above SB3's defaults (2,048 x 4).
MAX_ENVS = 1 << 16
#: Largest ``data`` entry read (its JSON holds a few kilobytes of pickles), and
#: largest tensor entry (``policy.pth``; the networks above stay far below it).
MAX_DATA_BYTES = 16 << 20
MAX_TENSOR_FILE_BYTES = 512 << 20
#: The entries SB3 writes in its zip; any other entry refuses the file.
_ENTRIES = frozenset(
    {
        "data",
        "policy.pth",
        "policy.optimizer.pth",
        "pytorch_variables.pth",
        "_stable_baselines3_version",
        "system_info.txt",
    }
)

#: ``check(key, value, data, source)``: the value the model gets for ``data[key]``.
_Check = Callable[[str, Any, Mapping[str, Any], str], Any]


def _pickled(value: Any) -> bool:
    """Whether SB3's ``load`` would unpickle this value of ``data`` (its own test)."""
    return isinstance(value, dict) and ":serialized:" in value


def _named(source: str, key: str) -> str:
    return f"{source}: data {key!r}"


def _integer(minimum: int, maximum: int) -> _Check:
    def check(key: str, value: Any, data: Mapping[str, Any], source: str) -> int:
        return check_integer(
            _named(source, key), value, minimum=minimum, maximum=maximum, error=RLConfigError
        )

    return check


def _number(minimum: float | None = None) -> _Check:
    def check(key: str, value: Any, data: Mapping[str, Any], source: str) -> float:
        return check_number(_named(source, key), value, minimum=minimum, error=RLConfigError)

    return check


def _optional_number(key: str, value: Any, data: Mapping[str, Any], source: str) -> float | None:
    return None if value is None else _number(0.0)(key, value, data, source)


def _flag(key: str, value: Any, data: Mapping[str, Any], source: str) -> bool:
    if not isinstance(value, bool):
        raise RLConfigError(f"{_named(source, key)} {value!r} is not true or false")
    return value


def _false(key: str, value: Any, data: Mapping[str, Any], source: str) -> bool:
    if value is not False:
        raise RLConfigError(f"{_named(source, key)} {value!r}: only false is supported")
    return False


def _none(key: str, value: Any, data: Mapping[str, Any], source: str) -> None:
    """Training state SB3 rebuilds when it is missing (``learn`` resets the env), or a
    value taken from the caller only (``tensorboard_log``): never the file's."""
    return None


def _no_noise(key: str, value: Any, data: Mapping[str, Any], source: str) -> None:
    if value is not None:
        raise RLConfigError(f"{_named(source, key)} is not supported by A2C/PPO (must be null)")
    return None


def _empty(key: str, value: Any, data: Mapping[str, Any], source: str) -> dict:
    if value not in (None, {}):
        raise RLConfigError(f"{_named(source, key)} {value!r}: only an empty one is supported")
    return {}


def _optional_seed(key: str, value: Any, data: Mapping[str, Any], source: str) -> int | None:
    return None if value is None else _integer(0, 2**64 - 1)(key, value, data, source)


def _lr_schedule(key: str, value: Any, data: Mapping[str, Any], source: str) -> str:
    """SB3 rebuilds the schedule from ``learning_rate`` anyway: the same, from the number."""
    _number(0.0)("learning_rate", data.get("learning_rate"), data, source)
    return REBUILD


def _clip_range(key: str, value: Any, data: Mapping[str, Any], source: str) -> float | None:
    """PPO's clip range: the constant of the ``ConstantSchedule`` described beside the pickle."""
    if value is None and key == "clip_range_vf":
        return None
    description = value.get("value_schedule") if isinstance(value, dict) else None
    match = _CONSTANT_SCHEDULE.fullmatch(description) if isinstance(description, str) else None
    try:
        number = float(match.group(1)) if match else math.nan
    except ValueError:
        number = math.nan
    if not (math.isfinite(number) and number > 0):
        raise RLConfigError(
            f"{_named(source, key)} is not a constant schedule ({description!r});"
            " it is refused rather than unpickled"
        )
    return number


def _rollout_buffer(key: str, value: Any, data: Mapping[str, Any], source: str) -> str:
    """The rollout buffer of Box observations (SB3's own choice for them)."""
    return REBUILD


def _kwargs_class(name: str, value: Any, source: str) -> str:
    if not isinstance(value, str) or value not in POLICY_KWARGS_CLASS_NAMES:
        raise RLConfigError(
            f"{source}: policy_kwargs[{name!r}] is {value!r}, not a class this loader rebuilds"
            " without unpickling"
        )
    return value


def _net_arch(value: Any, source: str) -> Any:
    name = f"{source}: policy_kwargs net_arch"
    if isinstance(value, dict):
        unknown = sorted(set(value) - {"pi", "vf"})
        if unknown:
            raise RLConfigError(f"{name} has keys {unknown}: only pi and vf")
        return {
            k: list(check_layer_widths(f"{name} {k}", v, error=RLConfigError))
            for k, v in value.items()
        }
    return list(check_layer_widths(name, value, error=RLConfigError))


def _extractor_kwargs(value: Any, source: str) -> dict[str, Any]:
    if not isinstance(value, dict) or set(value) - {"features_dim", "normalized_image"}:
        raise RLConfigError(
            f"{source}: policy_kwargs features_extractor_kwargs {value!r} takes features_dim"
            " (and normalized_image) only"
        )
    checked = dict(value)
    if "features_dim" in value:
        checked["features_dim"] = check_integer(
            f"{source}: policy_kwargs features_dim",
            value["features_dim"],
            minimum=1,
            maximum=MAX_LAYER_WIDTH,
            error=RLConfigError,
        )
    if "normalized_image" in value and not isinstance(value["normalized_image"], bool):
        raise RLConfigError(f"{source}: policy_kwargs normalized_image is not true or false")
    return checked


def _optimizer_kwargs(value: Any, source: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise RLConfigError(f"{source}: policy_kwargs optimizer_kwargs {value!r} is not an object")
    checked: dict[str, Any] = {}
    for name, item in value.items():
        items = item if isinstance(item, list) and len(item) <= 4 else [item]
        for number in items:
            if not isinstance(number, bool):
                check_number(
                    f"{source}: policy_kwargs optimizer_kwargs {name!r}",
                    number,
                    error=RLConfigError,
                )
        checked[name] = item
    return checked


#: What each key of ``policy_kwargs`` may hold: ``check(name, value, source)``.
_POLICY_KWARGS: dict[str, Callable[[str, Any, str], Any]] = {
    "net_arch": lambda name, value, source: _net_arch(value, source),
    "features_extractor_class": _kwargs_class,
    "features_extractor_kwargs": lambda name, value, source: _extractor_kwargs(value, source),
    "activation_fn": _kwargs_class,
    "optimizer_class": _kwargs_class,
    "optimizer_kwargs": lambda name, value, source: _optimizer_kwargs(value, source),
    "log_std_init": lambda name, value, source: check_number(
        f"{source}: policy_kwargs log_std_init", value, error=RLConfigError
    ),
    **{
        flag: lambda name, value, source: _flag(f"policy_kwargs {name}", value, {}, source)
        for flag in (
            "ortho_init",
            "normalize_images",
            "share_features_extractor",
            "squash_output",
            "full_std",
            "use_expln",
        )
    },
}


def _policy_kwargs(key: str, value: Any, data: Mapping[str, Any], source: str) -> dict:
    """The policy's keyword arguments from the JSON copy of their items SB3 stores.

    Each key must be one of :data:`_POLICY_KWARGS` and hold what it allows;
    classes (stored as ``str(cls)``) must be one of :data:`POLICY_KWARGS_CLASS_NAMES`;
    network sizes are bounded before anything is built.
    """
    if _pickled(value):
        if value.get(":type:") != str(dict):
            raise RLConfigError(f"{_named(source, key)} is not a dict ({value.get(':type:')!r})")
    elif not isinstance(value, dict):
        raise RLConfigError(f"{_named(source, key)} {value!r} is not an object")
    kwargs: dict[str, Any] = {}
    for name, item in value.items():
        if name in (":type:", ":serialized:", "device"):  # SB3 drops the device itself
            continue
        if name not in _POLICY_KWARGS:
            raise RLConfigError(
                f"{source}: policy_kwargs {name!r} is not one this loader reads"
                f" (it reads {', '.join(sorted(_POLICY_KWARGS))})"
            )
        kwargs[name] = _POLICY_KWARGS[name](name, item, source)
    return kwargs


#: Every key of ``data`` SB3's A2C and PPO write, and what it may hold. The
#: policy class and the spaces come from the robot (:func:`_checked_data`).
_DATA: dict[str, _Check] = {
    "verbose": _integer(0, 2),
    "policy_kwargs": _policy_kwargs,
    "num_timesteps": _integer(0, 2**63 - 1),
    "_total_timesteps": _integer(0, 2**63 - 1),
    "_num_timesteps_at_start": _integer(0, 2**63 - 1),
    "_episode_num": _integer(0, 2**63 - 1),
    "_n_updates": _integer(0, 2**63 - 1),
    "seed": _optional_seed,
    "action_noise": _no_noise,
    "start_time": _number(),
    "learning_rate": _number(0.0),
    "lr_schedule": _lr_schedule,
    "tensorboard_log": _none,
    "_last_obs": _none,
    "_last_episode_starts": _none,
    "_last_original_obs": _none,
    "ep_info_buffer": _none,
    "ep_success_buffer": _none,
    "use_sde": _false,
    "sde_sample_freq": _integer(-1, 2**31),
    "_current_progress_remaining": _number(),
    "_stats_window_size": _integer(1, 1 << 20),
    "n_envs": _integer(1, MAX_ENVS),
    "n_steps": _integer(1, MAX_ROLLOUT_SAMPLES),
    "gamma": _number(0.0),
    "gae_lambda": _number(0.0),
    "ent_coef": _number(),
    "vf_coef": _number(),
    "max_grad_norm": _number(0.0),
    "rollout_buffer_class": _rollout_buffer,
    "rollout_buffer_kwargs": _empty,
    "normalize_advantage": _flag,
}
#: ... and the keys of one algorithm only.
_DATA_BY_ALGORITHM: dict[str, dict[str, _Check]] = {
    "a2c": {},
    "ppo": {
        "batch_size": _integer(1, MAX_ROLLOUT_SAMPLES),
        "n_epochs": _integer(1, 1 << 16),
        "clip_range": _clip_range,
        "clip_range_vf": _clip_range,
        "target_kl": _optional_number,
    },
}


def _stored_shape(entry: Any) -> tuple[int, ...] | None:
    """The shape SB3 wrote beside a pickled space (``_shape``), if readable."""
    shape = entry.get("_shape") if isinstance(entry, dict) else None
    if isinstance(shape, list) and all(type(n) is int for n in shape):
        return tuple(shape)
    return None


def checked_data(
    data: Mapping[str, Any], algo: str, robot: Robot, given: Mapping[str, Any], source: str
) -> dict[str, Any]:
    """Every value of ``data``, checked: what the model gets (SB3's ``custom_objects``).

    The policy class and the spaces are left out: they come from the robot
    (the stored spaces' shapes must be the robot's). A value the caller passes
    in ``given`` (keyword arguments of the load) replaces the stored one;
    every other key must be one of :data:`_DATA` (for ``algo``) and hold what
    it allows. Any other key (say ``env``, which SB3 would hand to
    ``gym.make``, importing the module it names) refuses the file by name:
    nothing of the file reaches the model unchecked. Objects SB3's classes
    rebuild are :data:`REBUILD`; ``policy_kwargs`` classes are their names.
    The rollout's size is bounded before SB3 allocates it.
    """
    for key, space in (
        ("observation_space", observation_space(robot)),
        ("action_space", action_space(robot)),
    ):
        stored, expected = _stored_shape(data.get(key)), tuple(space.shape)
        if stored is not None and stored != expected:
            raise RLConfigError(
                f"{source}: its {key} has shape {stored}, robot {robot.to_string()}'s has"
                f" {expected}: the model was trained for another robot"
            )
    stored = "ppo" if "clip_range" in data else "a2c"  # PPO's own hyperparameter
    if stored != algo:
        raise RLConfigError(f"{source} was saved by {stored.upper()}, not {algo.upper()}")
    checks = {**_DATA, **_DATA_BY_ALGORITHM[algo]}
    custom: dict[str, Any] = {}
    for key, value in data.items():
        if key in ("policy_class", "observation_space", "action_space"):
            continue
        if key in given:
            custom[key] = given[key]
        elif key in checks:
            custom[key] = checks[key](key, value, data, source)
        else:
            kind = f" (a pickled {value.get(':type:')})" if _pickled(value) else ""
            raise RLConfigError(
                f"{source}: data {key!r}{kind} is not one that {algo.upper()} saves; the file"
                " is refused rather than read"
            )
    inputs = math.prod(observation_space(robot).shape)
    try:
        check_rollout_size(custom.get("n_steps", 1), custom.get("n_envs", 1), inputs)
    except ValueError as error:
        raise RLConfigError(f"{source}: {error}") from None
    return custom


def read_model_file(path: Path, source: str) -> tuple[bytes, dict[str, Any]]:
    """The file's bytes and its ``data`` object (its entries' sizes bounded and its names
    SB3's, before anything is inflated; the ``.pth`` entries are checked by
    :mod:`rl_baselines.agent`, with torch)."""
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise RLConfigError(f"{source} cannot be read: {error.strerror or error}") from None
    with zip_entries(
        raw,
        source,
        RLConfigError,
        max_entry_bytes=MAX_TENSOR_FILE_BYTES,
        max_total_bytes=MAX_DATA_BYTES + 3 * MAX_TENSOR_FILE_BYTES,
    ) as archive:
        infos = {info.filename: info for info in archive.infolist()}
        if "data" not in infos:
            raise RLConfigError(
                f"{source} has no 'data' entry (it is truncated, or not a model saved by SB3)"
            )
        unknown = sorted(set(infos) - _ENTRIES)
        if unknown:
            raise RLConfigError(
                f"{source} holds the entries {unknown}, which SB3 does not write: refused"
            )
        if infos["data"].file_size > MAX_DATA_BYTES:
            raise RLConfigError(
                f"{source}: its 'data' entry declares {infos['data'].file_size:,} bytes, more"
                f" than {MAX_DATA_BYTES:,}"
            )
        data = parse_json(
            read_entry(archive, "data", source, RLConfigError),
            f"{source}: its 'data' entry",
            error=RLConfigError,
        )
        if not isinstance(data, dict):
            raise RLConfigError(f"{source}: its 'data' entry is not a JSON object")
    return raw, data

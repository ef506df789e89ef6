"""SB3's hyperparameters of A2C and PPO, checked for the JAX trainer.

:func:`checked_hyperparameters` takes the keyword arguments a user would give
SB3's ``A2C``/``PPO`` (the names and defaults of their ``__init__``,
``stable_baselines3/a2c/a2c.py`` and ``ppo/ppo.py``) and returns the
:class:`Hyperparameters` the JAX trainer runs with. What the JAX trainer
implements is accepted; anything else raises :class:`~rl_baselines.RLConfigError`
naming it, never silently ignored:

* schedules (a callable ``learning_rate`` or ``clip_range``) are refused: the
  learning rate and clip ranges are constants (SB3's default);
* gSDE (``use_sde``), other rollout buffers, ``stats_window_size`` other than
  SB3's 100 (the JAX trainer reports per-rollout figures, not SB3's moving
  window) are refused, their defaults accepted;
* ``policy_kwargs`` may hold ``net_arch`` (a list, or ``dict(pi=..., vf=...)``),
  ``features_extractor_kwargs={"features_dim": n}`` for hybrid robots, and
  SB3's defaults of ``ortho_init``, ``share_features_extractor``,
  ``normalize_images`` and ``activation_fn`` (Tanh); nothing else;
* sizes are bounded before anything is allocated: layers by
  :func:`~amaze.validation.check_layer_widths`, ``features_dim`` by
  :data:`~amaze.validation.MAX_LAYER_WIDTH`, a rollout (``n_steps * n_envs``,
  and ``batch_size``) by :data:`MAX_ROLLOUT_SIZE`, an update's epochs by
  :data:`MAX_EPOCH_SAMPLES`.

SB3's defaults are written here (:data:`SB3_DEFAULTS`) so that the trainer
imports neither torch nor SB3; a test checks them against SB3's signatures.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from amaze.agents.robot import Robot
from amaze.validation import (
    MAX_LAYER_WIDTH,
    MAX_ROLLOUT_SAMPLES,
    check_integer,
    check_layer_widths,
    check_number,
    closest,
)
from rl_baselines import RLConfigError

__all__ = [
    "MAX_CHUNK_STEPS",
    "MAX_EPOCH_SAMPLES",
    "MAX_ROLLOUT_SIZE",
    "SB3_DEFAULTS",
    "Hyperparameters",
    "checked_hyperparameters",
    "observation_size",
]

#: The most samples (``n_steps * n_envs``) one rollout may hold, and the largest
#: ``batch_size`` (:data:`amaze.validation.MAX_ROLLOUT_SAMPLES`, shared with SB3
#: files): the rollout is allocated whole on the device. An observation is 8
#: float32s for DD, 15 x 15 bytes for H15 (about 17 GiB at the widest vision, 65).
MAX_ROLLOUT_SIZE = MAX_ROLLOUT_SAMPLES
#: The most samples the epochs of one PPO update go through (``n_epochs * n_steps
#: * n_envs``): the update draws them at once as int32 permutations (1 GiB at most).
MAX_EPOCH_SAMPLES = 2**28
#: The largest ``chunk_steps``: a call returns figures of every rollout it plays,
#: allocated up front (52 bytes per env step when rollouts are one step of one
#: env: 832 MiB here, 104 GiB at 2**31), and it must hold one rollout of the largest size
#: (:data:`~rl_baselines.jax.hyperparameters.MAX_ROLLOUT_SIZE`, which a saved
#: trainer records as its ``chunk_steps`` when a rollout is larger than a chunk).
MAX_CHUNK_STEPS = 2**24

_COMMON: dict[str, Any] = {
    "gamma": 0.99,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "use_sde": False,
    "sde_sample_freq": -1,
    "rollout_buffer_class": None,
    "rollout_buffer_kwargs": None,
    "stats_window_size": 100,
    "policy_kwargs": None,
}

#: SB3 2.x's defaults of the hyperparameters of ``A2C.__init__`` and ``PPO.__init__``
#: (the arguments the trainer sets itself, such as ``seed`` or ``device``, left out).
SB3_DEFAULTS: dict[str, dict[str, Any]] = {
    "a2c": {
        **_COMMON,
        "learning_rate": 7e-4,
        "n_steps": 5,
        "gae_lambda": 1.0,
        "rms_prop_eps": 1e-5,
        "use_rms_prop": True,
        "normalize_advantage": False,
    },
    "ppo": {
        **_COMMON,
        "learning_rate": 3e-4,
        "n_steps": 2048,
        "batch_size": 64,
        "n_epochs": 10,
        "gae_lambda": 0.95,
        "clip_range": 0.2,
        "clip_range_vf": None,
        "normalize_advantage": True,
        "target_kl": None,
    },
}

#: Hyperparameters accepted only at SB3's default value, and why.
_DEFAULT_ONLY = {
    "use_sde": "gSDE is for continuous actions; AMaze's JAX robots have discrete ones",
    "rollout_buffer_class": "the JAX trainer has its own rollout buffer (SB3's RolloutBuffer)",
    "rollout_buffer_kwargs": "the JAX trainer has its own rollout buffer (SB3's RolloutBuffer)",
    "stats_window_size": "the JAX trainer reports per-rollout figures, not SB3's moving window",
}

#: ``policy_kwargs`` accepted at SB3's defaults only (``activation_fn`` by its torch name).
_POLICY_DEFAULTS = {
    "ortho_init": True,
    "share_features_extractor": True,
    "normalize_images": True,
}


@dataclass(frozen=True)
class Hyperparameters:
    """What one A2C or PPO run of the JAX trainer uses (hashable: a static jit argument).

    Names and meanings are SB3's. ``batch_size`` and ``n_epochs`` are PPO's
    (A2C: one gradient step on the whole rollout, ``batch_size`` is the
    rollout's size and ``n_epochs`` 1); ``clip_range``, ``clip_range_vf`` and
    ``target_kl`` are PPO's (``None`` / unused for A2C); ``use_rms_prop`` and
    ``rms_prop_eps`` A2C's (PPO: Adam). ``net_pi`` / ``net_vf`` are the hidden
    layers of the policy and value MLPs; ``features_dim`` the CNN's output
    (hybrid robots).
    """

    algo: str
    n_envs: int
    learning_rate: float
    n_steps: int
    batch_size: int
    n_epochs: int
    gamma: float
    gae_lambda: float
    clip_range: float | None
    clip_range_vf: float | None
    normalize_advantage: bool
    ent_coef: float
    vf_coef: float
    max_grad_norm: float
    use_rms_prop: bool
    rms_prop_eps: float
    target_kl: float | None
    net_pi: tuple[int, ...]
    net_vf: tuple[int, ...]
    features_dim: int

    @property
    def rollout_size(self) -> int:
        """Env steps (samples) of one rollout: ``n_steps * n_envs``."""
        return self.n_steps * self.n_envs

    def sb3_kwargs(self, *, policy: bool = True) -> dict[str, Any]:
        """The keyword arguments that build the same SB3 model (for :func:`new_sb3_model`).

        ``policy`` False: without ``policy_kwargs`` (a network spec gives the policy).
        """
        kwargs: dict[str, Any] = {
            name: getattr(self, name) for name in SB3_DEFAULTS[self.algo] if hasattr(self, name)
        }
        if not policy:
            return kwargs
        net_arch = {"pi": list(self.net_pi), "vf": list(self.net_vf)}
        policy_kwargs: dict[str, Any] = {"net_arch": net_arch}
        if self.features_dim != 64:
            policy_kwargs["features_extractor_kwargs"] = {"features_dim": self.features_dim}
        kwargs["policy_kwargs"] = policy_kwargs
        return kwargs


def _layers(name: str, value: Any) -> tuple[int, ...]:
    """A list of layer widths (``net_arch``), bounded by :func:`check_layer_widths`."""
    return check_layer_widths(f"policy_kwargs {name}", value, error=RLConfigError)


def _net_arch(value: Any) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """``net_arch`` as SB3's ``MlpExtractor`` reads it: a list for both nets, or pi/vf."""
    if isinstance(value, Mapping):
        unknown = set(value) - {"pi", "vf"}
        if unknown:
            raise RLConfigError(f"policy_kwargs net_arch has keys {sorted(unknown)}: use pi, vf")
        return _layers("net_arch pi", value.get("pi", [])), _layers(
            "net_arch vf", value.get("vf", [])
        )
    layers = _layers("net_arch", value)
    return layers, layers


def _policy_kwargs(value: Any, image: bool) -> tuple[tuple[int, ...], tuple[int, ...], int]:
    """``(net_pi, net_vf, features_dim)`` from ``policy_kwargs`` (see the module docstring)."""
    net_pi = net_vf = (64, 64)
    features_dim = 64
    if value is None:
        return net_pi, net_vf, features_dim
    if not isinstance(value, Mapping):
        raise RLConfigError(f"hyperparameter 'policy_kwargs' {value!r} is not a JSON object")
    for name, item in value.items():
        if name == "net_arch":
            net_pi, net_vf = _net_arch(item)
        elif name == "features_extractor_kwargs" and image:
            if not isinstance(item, Mapping) or set(item) - {"features_dim"}:
                raise RLConfigError(
                    f"policy_kwargs features_extractor_kwargs {item!r}: the JAX trainer's"
                    " SmallCNN takes features_dim only"
                )
            features_dim = check_integer(
                "policy_kwargs features_dim",
                item.get("features_dim", 64),
                minimum=1,
                maximum=MAX_LAYER_WIDTH,
                error=RLConfigError,
            )
        elif name in _POLICY_DEFAULTS and item is _POLICY_DEFAULTS[name]:
            continue
        elif name == "activation_fn" and getattr(item, "__name__", None) == "Tanh":
            continue
        else:
            raise RLConfigError(
                f"policy_kwargs {name!r} = {item!r} is not supported by the JAX trainer"
                " (it takes net_arch, and features_extractor_kwargs features_dim for"
                " hybrid robots)"
            )
    return net_pi, net_vf, features_dim


def _number(
    name: str, value: Any, *, positive: bool = False, unit: bool = False, signed: bool = False
) -> float:
    """A finite float: >= 0 (``signed``: any; ``positive``: > 0; ``unit``: in [0, 1]).

    A callable is a schedule, refused.
    """
    if callable(value):
        raise RLConfigError(
            f"hyperparameter {name!r} is a schedule: the JAX trainer takes constants only"
        )
    number = check_number(
        f"hyperparameter {name!r}",
        value,
        minimum=None if signed else 0.0,
        maximum=1.0 if unit else None,
        strict_minimum=positive,
        error=RLConfigError,
    )
    return float(number)


def _optional(name: str, value: Any) -> float | None:
    return None if value is None else _number(name, value, positive=True)


def _bool(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise RLConfigError(f"hyperparameter {name!r} {value!r} is not true or false")
    return value


def checked_hyperparameters(
    algo: str, hyperparameters: Mapping[str, Any], *, robot_images: bool, n_envs: int = 4
) -> Hyperparameters:
    """SB3's defaults for ``algo`` updated with ``hyperparameters``, every value checked.

    ``robot_images``: the robot sees images (a hybrid robot), which allows
    ``features_extractor_kwargs``. Unknown names, schedules and unsupported
    options raise :class:`RLConfigError` naming them (see the module docstring).
    """
    name = str(algo).lower()
    if name not in SB3_DEFAULTS:
        raise RLConfigError(f"unknown algorithm {algo!r} (choose from a2c, ppo)")
    defaults = SB3_DEFAULTS[name]
    for key in hyperparameters:
        if key not in defaults:
            raise RLConfigError(
                f"hyperparameter {key!r} is not one of {name.upper()}'s{closest(key, defaults)}"
            )
    given = {**defaults, **hyperparameters}
    for key, why in _DEFAULT_ONLY.items():
        if given[key] != defaults[key] and not (key.endswith("kwargs") and given[key] == {}):
            raise RLConfigError(f"hyperparameter {key!r} = {given[key]!r} is refused: {why}")
    check_integer("hyperparameter 'sde_sample_freq'", given["sde_sample_freq"], error=RLConfigError)
    n_envs = check_integer(
        "n_envs", n_envs, minimum=1, maximum=MAX_ROLLOUT_SIZE, error=RLConfigError
    )
    n_steps = check_integer(
        "hyperparameter 'n_steps'",
        given["n_steps"],
        minimum=1,
        maximum=MAX_ROLLOUT_SIZE,
        error=RLConfigError,
    )
    if n_steps * n_envs > MAX_ROLLOUT_SIZE:
        raise RLConfigError(
            f"n_steps * n_envs = {n_steps} * {n_envs} = {n_steps * n_envs:,} samples a rollout,"
            f" more than {MAX_ROLLOUT_SIZE:,}"
        )
    net_pi, net_vf, features_dim = _policy_kwargs(given["policy_kwargs"], robot_images)
    ppo = name == "ppo"
    normalize = _bool("normalize_advantage", given["normalize_advantage"])
    batch_size = n_steps * n_envs
    n_epochs = 1
    if ppo:
        batch_size = check_integer(
            "hyperparameter 'batch_size'",
            given["batch_size"],
            minimum=1,
            maximum=MAX_ROLLOUT_SIZE,
            error=RLConfigError,
        )
        n_epochs = check_integer(
            "hyperparameter 'n_epochs'", given["n_epochs"], minimum=1, error=RLConfigError
        )
        if n_epochs * n_steps * n_envs > MAX_EPOCH_SAMPLES:
            raise RLConfigError(
                f"n_epochs * n_steps * n_envs = {n_epochs * n_steps * n_envs:,} samples an"
                f" update, more than {MAX_EPOCH_SAMPLES:,}"
            )
        if normalize and batch_size < 2:
            raise RLConfigError("hyperparameter 'batch_size' must be > 1 to normalize advantages")
    if normalize and n_steps * n_envs < 2:
        raise RLConfigError("n_steps * n_envs must be > 1 to normalize advantages")
    return Hyperparameters(
        algo=name,
        n_envs=n_envs,
        learning_rate=_number("learning_rate", given["learning_rate"], positive=True),
        n_steps=n_steps,
        batch_size=batch_size,
        n_epochs=n_epochs,
        gamma=_number("gamma", given["gamma"], unit=True),
        gae_lambda=_number("gae_lambda", given["gae_lambda"], unit=True),
        clip_range=_number("clip_range", given["clip_range"], positive=True) if ppo else None,
        clip_range_vf=_optional("clip_range_vf", given.get("clip_range_vf")),
        normalize_advantage=normalize,
        ent_coef=_number("ent_coef", given["ent_coef"], signed=True),
        vf_coef=_number("vf_coef", given["vf_coef"]),
        max_grad_norm=_number("max_grad_norm", given["max_grad_norm"], positive=True),
        use_rms_prop=_bool("use_rms_prop", given.get("use_rms_prop", False)),
        rms_prop_eps=_number("rms_prop_eps", given.get("rms_prop_eps", 1e-5), positive=True),
        target_kl=_optional("target_kl", given.get("target_kl")),
        net_pi=net_pi,
        net_vf=net_vf,
        features_dim=features_dim,
    )


def observation_size(robot: Robot) -> int:
    """The numbers of one observation of ``robot`` (8 inputs, or its retina's pixels)."""
    return 8 if robot.discrete_inputs else robot.vision * robot.vision

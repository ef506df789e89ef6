"""A JAX trainer's policy as a run's agent: evaluated in numpy, saved as an SB3 agent.

:class:`JaxAgent` is what a ``--framework jax`` run hands over and evaluates:
the policy of the trainer at the moment the agent was taken (a snapshot: the
trainer training on does not change it), acting deterministically through
:class:`~rl_baselines.jax.policy.NumpyPolicy` (no torch, no compilation per
batch size). :meth:`JaxAgent.save` writes it as SB3 writes its agents (the
zip and the JSON beside it, :func:`rl_baselines.jax.sb3_io.export_sb3`), so
``agent.zip`` of a JAX run is read by :meth:`rl_baselines.agent.SB3Agent.load`,
``amaze evaluate`` and ``amaze run`` exactly as an SB3 run's.

A ``network`` kind's policy (:mod:`rl_baselines.jax.spec`) is not an SB3
policy: its actor is saved as an evolved agent's file (``agent.npz``,
:mod:`amaze.agents.agent_file`, architecture ``mlp`` with the same spec), which
``amaze evaluate`` plays with evolution's compiled networks, and which
:class:`NetworkAgent` reads back (a champion handed over, a run resumed).
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from amaze.agents.agent_file import AgentFileError, read_agent, save_agent
from amaze.errors import AmazeError
from rl_baselines import RLConfigError
from rl_baselines.jax.policy import NumpyPolicy
from rl_baselines.jax.spec import NETWORK_KEYS, PolicySpec, network_spec

if TYPE_CHECKING:
    from rl_baselines.jax.trainer import JaxTrainer

__all__ = ["JaxAgent", "NetworkAgent", "NetworkRunFiles"]


class JaxAgent:
    """The policy of ``trainer`` now, deterministic; ``save`` writes an SB3 agent."""

    def __init__(self, trainer: JaxTrainer) -> None:
        self._trainer = copy.copy(trainer)  # its state is immutable arrays: a snapshot
        self.policy = trainer.policy()
        self.robot = self.policy.robot
        self.algo = trainer.hyperparameters.algo
        #: Env steps the policy was trained on.
        self.num_timesteps = trainer.num_timesteps

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions for a batch of observations (int64 ``(n,)``, or a
        continuous robot's float64 ``(n, 2)`` accelerations)."""
        return self.policy(observations)

    def params(self) -> dict[str, dict[str, np.ndarray]]:
        """The policy's parameters (SB3's names, torch's layout)."""
        return self.policy.params

    def save(self, path: str | os.PathLike) -> Path:
        """The SB3 zip (and its JSON) of the policy and optimizer state; the zip's path.

        A ``network`` kind's policy: its actor as an evolved agent's file
        (:meth:`NetworkAgent.save`), ``path`` ending in ``.npz``.
        """
        if self.policy.spec.kind == "network":
            agent = NetworkAgent(self.policy.spec, self.params(), self.algo, self.num_timesteps)
            return agent.save(path)
        return self._trainer.export_sb3(path)


class NetworkAgent:
    """A ``network`` kind's actor, deterministic, as an evolved agent's file holds it.

    ``params``: the actor's modules at least (SB3's names, torch's layout);
    ``algo`` and ``num_timesteps`` are recorded in the file's metadata.
    """

    def __init__(
        self,
        spec: PolicySpec,
        params: Mapping[str, Mapping[str, np.ndarray]],
        algo: str,
        num_timesteps: int,
    ) -> None:
        self.policy = NumpyPolicy(spec, params, actor_only=True)
        self.robot = self.policy.robot
        self.algo = algo
        self.num_timesteps = num_timesteps

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """Deterministic actions for a batch of observations (int64 ``(n,)``, or a
        continuous robot's float64 ``(n, 2)`` accelerations)."""
        return self.policy(observations)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the actor as an evolved agent's file (atomically); its path."""
        spec = self.policy.spec
        path = Path(path)
        if path.suffix != ".npz":
            raise RLConfigError(f"a network agent is saved as an .npz file, not '{path}'")
        metadata = {
            "architecture": spec.architecture(),
            "robot": spec.robot,
            "trainer": "rl",
            "algorithm": self.algo,
            "num_timesteps": self.num_timesteps,
        }
        vector = spec.actor_vector(self.policy.params)
        return save_agent(path, {"params": vector}, metadata, error=RLAgentFileError)

    @classmethod
    def load(cls, path: str | os.PathLike) -> NetworkAgent:
        """The agent in ``path`` (written by :meth:`save`), checked before it is read.

        A file of another architecture (a NEAT genome, a convolutional
        network) or a damaged one raises :class:`RLConfigError` naming it.
        """
        where = f"network agent '{path}'"
        specs: list[PolicySpec] = []

        def expect(metadata: Mapping[str, Any], where: str) -> Any:
            specs.append(_spec_of(metadata, where))
            n_params = specs[0].actor_vector_size()

            def check(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
                if name != "params" or shape != (n_params,) or dtype.kind != "f":
                    raise RLAgentFileError(
                        f"{where}: holds {name!r} ({dtype}, {shape}), not {n_params} floats"
                        " 'params'"
                    )

            return check

        arrays, metadata = read_agent(path, expect, error=RLAgentFileError)
        if "params" not in arrays:
            raise RLAgentFileError(f"{where} has no 'params'")
        spec = specs[0]
        steps = metadata.get("num_timesteps", 0)
        return cls(
            spec,
            spec.actor_from_vector(arrays["params"]),
            str(metadata.get("algorithm", "")),
            steps if isinstance(steps, int) else 0,
        )


class RLAgentFileError(RLConfigError, AgentFileError):
    """A network agent's file is missing, damaged, or not an RL network's (both error kinds)."""


def _spec_of(metadata: Mapping[str, Any], where: str) -> PolicySpec:
    """The ``network`` kind's spec an agent file's metadata describes, or the error naming it."""
    architecture = metadata["architecture"]
    if architecture.get("type") != "mlp":
        raise RLAgentFileError(
            f"{where}: architecture {architecture!r} is not a network the RL learners train"
            " (a fixed-topology network, not a NEAT genome)"
        )
    network = {key: architecture[key] for key in NETWORK_KEYS if key in architecture}
    try:
        return network_spec(architecture.get("robot", metadata.get("robot")), network)
    except (RLConfigError, AmazeError, TypeError) as error:
        raise RLAgentFileError(f"{where}: {error}") from None


class NetworkRunFiles:
    """The agent files of a JAX run: SB3's, or with a ``network`` spec evolved agents' files.

    Mixed into the JAX runs before their base: ``agent.npz`` and
    ``checkpoints/champion.npz`` instead of ``agent.zip`` and
    ``checkpoints/champion.zip``, read back by :meth:`NetworkAgent.load`;
    :meth:`network_figures` is what ``summary.json`` records of the network.
    """

    config: Any

    @property
    def agent_file(self) -> str:
        return "agent.zip" if self.config.network is None else "agent.npz"

    @property
    def champion_file(self) -> Path:
        champion = super().champion_file  # type: ignore[misc]
        return champion if self.config.network is None else champion.with_suffix(".npz")

    def load_agent(self, path: Path) -> Any:
        """The agent saved at ``path`` (a champion), checked: SB3's zip or a network's file."""
        if self.config.network is None:
            return super().load_agent(path)  # type: ignore[misc]
        return NetworkAgent.load(path)

    def replayed_agent(self, path: Path, agent: Any) -> Any:
        """A network's saved actor as ``amaze evaluate`` plays it: evolution's compiled network.

        Its float32 sums differ from :class:`NetworkAgent`'s numpy ones in the last
        bits (about 1e-6 in an acceleration), and a continuous robot's trajectory,
        once it differs, goes its own way: the run scores the file as it is
        replayed, so that ``summary.json`` is what ``amaze evaluate`` gives.
        """
        if self.config.network is None:
            return agent
        from amaze.evaluation.controllers import make_controller

        return make_controller(str(path), self.config.robot)

    def network_figures(self) -> dict[str, Any]:
        """``{"network": architecture}`` with a network spec (``summary.json``), else nothing.

        A continuous robot (which trains only with a network) paid the progress
        reward adds ``progress_reward``, so that the run says what it trained for.
        """
        c = self.config
        if c.network is None:
            return {}
        figures: dict[str, Any] = {"network": network_spec(c.robot, c.network).architecture()}
        if c.progress_reward:
            figures["progress_reward"] = c.progress_reward
        return figures

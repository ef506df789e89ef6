"""Evolved agents on disk: the ``amaze-evo-agent`` files of :mod:`amaze.agents.agent_file`.

The format (one ``.npz`` of arrays plus JSON metadata, never pickled, written
atomically, read with every size bounded first) is defined in
:mod:`amaze.agents.agent_file`, shared with ``rl_baselines``. Here are its
evolution-specific parts: what a fixed network (``mlp``, a
:class:`~evolution.networks.NetworkSpec`'s ``params``) or a NEAT-like genome
(``neat``) must hold, and the policy it plays. Errors are this module's
:class:`AgentFileError` (an :class:`~evolution.EvolutionConfigError`).
:func:`load_agent` is registered as the ``npz`` loader of
``amaze.agent_loaders``, so ``amaze run --controller champion.npz`` (and
``amaze inputs``, ``amaze suite --evaluate``) play saved agents.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents import agent_file as _format
from amaze.agents.agent_file import (
    FORMAT,
    FORMAT_VERSION,
    MAX_AGENT_BYTES,
    MAX_ARRAY_BYTES,
    MAX_METADATA_BYTES,
    METADATA_KEY,
    SUFFIX,
    ArrayCheck,
)
from amaze.agents.robot import RobotStringError, as_robot
from evolution import EvolutionConfigError
from evolution.networks import NetworkSpec

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "MAX_AGENT_BYTES",
    "MAX_ARRAY_BYTES",
    "MAX_METADATA_BYTES",
    "METADATA_KEY",
    "SUFFIX",
    "AgentFileError",
    "load_agent",
    "policy_from_agent_arrays",
    "read_agent",
    "save_agent",
    "save_network_agent",
]


class AgentFileError(EvolutionConfigError, _format.AgentFileError):
    """An agent file is missing, unreadable, of another format or inconsistent.

    It is an :class:`~evolution.EvolutionConfigError` and an
    :class:`amaze.agents.agent_file.AgentFileError` (so an
    :class:`~amaze.errors.AmazeError`, which the ``amaze`` command reports as
    a one-line error).
    """


def save_agent(
    path: str | os.PathLike, arrays: Mapping[str, np.ndarray], metadata: Mapping[str, Any]
) -> Path:
    """Write an agent file atomically and return its path (``.npz`` is appended if missing).

    ``metadata`` must hold ``architecture`` (a mapping with a ``type``) and
    ``robot``; ``format`` and ``version`` are set here. Arrays must be numeric
    or boolean (no objects: the file is read without pickle). As
    :func:`amaze.agents.agent_file.save_agent`, raising :class:`AgentFileError`.
    """
    return _format.save_agent(path, arrays, metadata, error=AgentFileError)


def save_network_agent(
    path: str | os.PathLike, spec: NetworkSpec, params: np.ndarray, **metadata: Any
) -> Path:
    """Save one fixed network (``params``: ``(spec.n_params,)``) with ``metadata``.

    Typical metadata: ``mazes`` (training maze strings), ``fitness``,
    ``algorithm``, ``generation``, ``seed``.
    """
    params = np.asarray(params, dtype=np.float64)
    if params.shape == (1, spec.n_params):
        params = params[0]
    if params.shape != (spec.n_params,):
        raise EvolutionConfigError(
            f"a network of {spec.n_params} parameters was expected, got shape {params.shape}"
        )
    meta = {**metadata, "architecture": {"type": "mlp", **spec.to_dict()}, "robot": spec.robot}
    return save_agent(path, {"params": params}, meta)


def read_agent(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays and the metadata of an agent file, checked (format, version, architecture).

    As :func:`amaze.agents.agent_file.read_agent`, with a fixed network's
    ``params`` checked against its spec before they are read; raises
    :class:`AgentFileError` naming the file.
    """
    return _format.read_agent(path, _expected_arrays, error=AgentFileError)


def _expected_arrays(metadata: Mapping[str, Any], where: str) -> ArrayCheck:
    """What the arrays of an agent must be, from its metadata, checked before they are read.

    A fixed network (``mlp``) holds ``params``: exactly the spec's parameters
    (:func:`amaze.agents.agent_file.read_agent` checks that every array holds
    numbers). A NEAT-like genome's arrays are bounded by
    :data:`~amaze.agents.agent_file.MAX_ARRAY_BYTES` (checked on opening) and
    checked in full once read.
    """
    architecture = metadata["architecture"]
    n_params = None
    if architecture["type"] == "mlp":
        try:
            n_params = NetworkSpec.from_dict(architecture).n_params
        except EvolutionConfigError as error:
            raise AgentFileError(f"{where}: {error}") from None

    def expect(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
        if n_params is not None and name == "params" and shape != (n_params,):
            raise AgentFileError(
                f"{where}: 'params' must be {n_params} floats, got {dtype} of shape {shape}"
            )

    return expect


def load_agent(path: str | os.PathLike) -> Any:
    """The policy saved in ``path`` (one individual; it has a ``robot`` attribute).

    Args:
        path: an agent file written by :func:`save_agent` (``agent.npz`` of a run).

    Returns:
        A :class:`~evolution.networks.NetworkPopulation` of one for a fixed network
            (``mlp``), the compiled population of one of a NEAT-like genome (``neat``).

    Raises:
        AgentFileError: the file is missing, damaged or hostile, named in the message.
    """
    arrays, metadata = read_agent(path)
    return policy_from_agent_arrays(arrays, metadata, where=f"agent file '{path}'")


def policy_from_agent_arrays(
    arrays: Mapping[str, np.ndarray], metadata: Mapping[str, Any], where: str = "agent"
) -> Any:
    """The policy of an agent's ``arrays`` and ``metadata`` (``architecture``, ``robot``).

    What :func:`load_agent` does once the file is read; an agent held in
    memory (a search algorithm's champion arrays) is built the same way.
    Inconsistent arrays raise :class:`AgentFileError` starting with ``where``.
    """
    arrays = dict(arrays)
    architecture = metadata["architecture"]
    kind = architecture["type"]
    try:
        robot = as_robot(metadata.get("robot", ""))
    except (RobotStringError, TypeError, AttributeError):
        raise AgentFileError(
            f"{where}: robot {metadata.get('robot')!r} is not a robot string"
        ) from None
    if kind == "mlp":
        try:
            spec = NetworkSpec.from_dict(architecture)
        except EvolutionConfigError as error:
            raise AgentFileError(f"{where}: {error}") from None
        if spec.robot_info != robot:
            raise AgentFileError(
                f"{where}: the network is for {spec.robot} robots, the metadata says {robot}"
            )
        params = arrays.get("params")
        if params is None or params.shape != (spec.n_params,) or params.dtype.kind != "f":
            found = "none" if params is None else f"{params.dtype} of shape {params.shape}"
            raise AgentFileError(f"{where}: 'params' must be {spec.n_params} floats, got {found}")
        try:
            return spec.population(params[None])
        except EvolutionConfigError as error:
            raise AgentFileError(f"{where}: {error}") from None
    if kind == "neat":
        from evolution.neat import policy_from_arrays

        try:
            return policy_from_arrays(arrays, architecture, robot.to_string())
        except AgentFileError:
            raise
        except (EvolutionConfigError, KeyError, ValueError, IndexError) as error:
            raise AgentFileError(f"{where}: {error}") from None
    raise AgentFileError(f"{where}: unknown architecture type {kind!r} (expected 'mlp' or 'neat')")

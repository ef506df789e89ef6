"""Evolved agents on disk: one ``.npz`` file of arrays plus JSON metadata, never pickled.

An agent file ``<name>.npz`` is a plain numpy archive, read with
``np.load(path, allow_pickle=False)``:

* the agent's arrays (``params`` for a fixed network; whatever
  :mod:`evolution.neat.compile` needs for a NEAT-like genome);
* ``metadata``: a 0-d unicode array holding one JSON object with
  ``format`` (``"amaze-evo-agent"``), ``version`` (:data:`FORMAT_VERSION`),
  ``architecture`` (``{"type": "mlp", ...}`` as :meth:`NetworkSpec.to_dict
  <evolution.networks.NetworkSpec.to_dict>`, or ``{"type": "neat", ...}``),
  ``robot`` (canonical string) and whatever the caller adds: the training
  mazes (``mazes``), ``fitness``, the algorithm and its settings...

Files are written atomically (a temporary file, then a rename), so that a
killed run never leaves half an agent. :func:`load_agent` returns a policy of
the :mod:`amaze.evaluation.policy` protocol for one individual, any number of agents at
once; it is registered as the ``npz`` loader of ``amaze.agent_loaders``, so
``amaze run --controller champion.npz`` (and ``amaze inputs``, ``amaze suite
--evaluate``) play saved agents.
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.robot import RobotStringError, as_robot
from amaze.errors import AmazeError
from evolution import EvolutionConfigError
from evolution.networks import NetworkSpec

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "AgentFileError",
    "load_agent",
    "policy_from_agent_arrays",
    "read_agent",
    "save_agent",
    "save_network_agent",
]

#: Identifies our agent files, and the version of their layout.
FORMAT = "amaze-evo-agent"
FORMAT_VERSION = 1
#: Name of the metadata entry in the archive (no array may use it).
METADATA_KEY = "metadata"
SUFFIX = ".npz"
#: The first bytes of a zip archive (an .npz; the second, of an empty one), as numpy
#: tells them, and of a single .npy array.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


class AgentFileError(EvolutionConfigError, AmazeError):
    """An agent file is missing, unreadable, of another format or inconsistent.

    It is an :class:`~evolution.EvolutionConfigError` and an
    :class:`~amaze.errors.AmazeError`, so that the ``amaze`` command reports it
    as a one-line error.
    """


def _agent_path(path: str | os.PathLike) -> Path:
    path = Path(path)
    return path if path.suffix == SUFFIX else path.with_name(path.name + SUFFIX)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if isinstance(value, tuple | set | frozenset):
        return list(value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{value!r} of type {type(value).__name__} is not JSON-serialisable")


def save_agent(
    path: str | os.PathLike, arrays: Mapping[str, np.ndarray], metadata: Mapping[str, Any]
) -> Path:
    """Write an agent file atomically and return its path (``.npz`` is appended if missing).

    ``metadata`` must hold ``architecture`` (a mapping with a ``type``) and
    ``robot``; ``format`` and ``version`` are set here. Arrays must be numeric
    or boolean (no objects: the file is read without pickle).
    """
    path = _agent_path(path)
    meta = dict(metadata)
    architecture = meta.get("architecture")
    if not isinstance(architecture, Mapping) or not isinstance(architecture.get("type"), str):
        raise EvolutionConfigError("agent metadata needs an 'architecture' with a 'type'")
    try:
        meta["robot"] = as_robot(meta.get("robot", "")).to_string()
    except (RobotStringError, TypeError, AttributeError):
        raise EvolutionConfigError(
            f"agent metadata: robot {meta.get('robot')!r} is not a robot string"
        ) from None
    meta["format"] = FORMAT
    meta["version"] = FORMAT_VERSION
    try:
        text = json.dumps(meta, default=_json_default, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as error:
        raise EvolutionConfigError(f"agent metadata is not JSON-serialisable: {error}") from None
    contents: dict[str, np.ndarray] = {}
    for name, array in arrays.items():
        if not isinstance(name, str) or not name or name == METADATA_KEY or "/" in name:
            raise EvolutionConfigError(f"array name {name!r} is not allowed in an agent file")
        array = np.asarray(array)
        if array.dtype.kind not in "biuf":
            raise EvolutionConfigError(
                f"array {name!r} has dtype {array.dtype}: only numbers and booleans are saved"
            )
        contents[name] = array
    contents[METADATA_KEY] = np.array(text)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as stream:
            np.savez(stream, **contents)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


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
    """The arrays and the metadata of an agent file, checked (format, version, architecture)."""
    path = Path(path)
    if not path.is_file():
        what = "is not a file" if path.exists() else "does not exist"
        raise AgentFileError(f"agent file '{path}' {what}")
    try:
        with path.open("rb") as stream:
            head = stream.read(len(_NPY_MAGIC))
        if head == _NPY_MAGIC:
            raise AgentFileError(f"agent file '{path}' holds a single array, not an .npz archive")
        if not head.startswith(_ZIP_MAGIC):  # numpy would try it as a pickle, and refuse it
            raise AgentFileError(f"agent file '{path}' is not a readable .npz archive: not a zip")
        archive = np.load(path, allow_pickle=False)
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise AgentFileError(f"agent file '{path}' holds a single array, not an .npz archive")
        with archive:
            contents = {name: archive[name] for name in archive.files}
    except AgentFileError:
        raise
    except (
        OSError,
        ValueError,
        EOFError,
        KeyError,
        RuntimeError,
        NotImplementedError,  # zipfile: an entry compressed by an unsupported method
        zipfile.BadZipFile,
        zlib.error,
    ) as error:
        raise AgentFileError(
            f"agent file '{path}' is not a readable .npz archive: {error}"
        ) from None
    for name, value in contents.items():
        if not isinstance(value, np.ndarray):  # numpy hands back the raw bytes of a non-.npy entry
            raise AgentFileError(f"agent file '{path}': entry {name!r} is not a .npy array")
    if METADATA_KEY not in contents:
        raise AgentFileError(f"agent file '{path}' has no '{METADATA_KEY}' entry")
    raw = contents.pop(METADATA_KEY)
    if raw.shape != () or raw.dtype.kind != "U":
        raise AgentFileError(f"agent file '{path}': '{METADATA_KEY}' is not a JSON string")
    try:
        metadata = json.loads(str(raw[()]))
    except (ValueError, RecursionError) as error:  # bad JSON, too deep, too many digits
        raise AgentFileError(f"agent file '{path}': metadata is not valid JSON ({error})") from None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise AgentFileError(f"agent file '{path}' is not an {FORMAT} file")
    version = metadata.get("version")
    if type(version) is not int or version != FORMAT_VERSION:
        raise AgentFileError(
            f"agent file '{path}' has format version {version!r}; this code reads version"
            f" {FORMAT_VERSION}"
        )
    architecture = metadata.get("architecture")
    if not isinstance(architecture, dict) or not isinstance(architecture.get("type"), str):
        raise AgentFileError(f"agent file '{path}': metadata has no valid 'architecture'")
    return contents, metadata


def load_agent(path: str | os.PathLike) -> Any:
    """The policy saved in ``path`` (one individual; it has a ``robot`` attribute).

    Fixed networks (``mlp``) give a :class:`~evolution.networks.NetworkPopulation`
    of one; NEAT-like genomes (``neat``) are built by ``evolution.neat.policy_from_arrays``.
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

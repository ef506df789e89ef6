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
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.robot import RobotStringError, as_robot
from amaze.archives import open_npz
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
#: Bounds checked before an agent file's arrays are inflated: one array, the
#: metadata string, and the whole file once inflated (agents are kilobytes).
MAX_ARRAY_BYTES = 64 << 20
MAX_METADATA_BYTES = 16 << 20
MAX_AGENT_BYTES = 256 << 20


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
    where = f"agent file '{path}'"
    try:
        with path.open("rb") as stream:
            head = stream.read(len(_NPY_MAGIC))
    except OSError as error:
        raise AgentFileError(f"{where} cannot be read: {error.strerror or error}") from None
    if head == _NPY_MAGIC:
        raise AgentFileError(f"{where} holds a single array, not an .npz archive")
    if not head.startswith(_ZIP_MAGIC):  # numpy would try it as a pickle, and refuse it
        raise AgentFileError(f"{where} is not a readable .npz archive: not a zip")
    with open_npz(
        path,
        where,
        AgentFileError,
        max_entry_bytes=MAX_ARRAY_BYTES,
        max_total_bytes=MAX_AGENT_BYTES,
    ) as archive:
        if METADATA_KEY not in archive.names:
            raise AgentFileError(f"{where} has no '{METADATA_KEY}' entry")
        raw = archive.read(METADATA_KEY, _metadata_header(where))
        metadata = _checked_metadata(raw, where)
        expect = _expected_arrays(metadata, where)
        contents = {
            name: archive.read(name, expect) for name in archive.names if name != METADATA_KEY
        }
    return contents, metadata


def _metadata_header(where: str) -> Callable[[str, tuple[int, ...], np.dtype], None]:
    """The metadata entry's header must be one string of at most :data:`MAX_METADATA_BYTES`."""

    def expect(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
        if shape != () or dtype.kind != "U":
            raise AgentFileError(f"{where}: '{METADATA_KEY}' is not a JSON string")
        if dtype.itemsize > MAX_METADATA_BYTES:
            raise AgentFileError(
                f"{where}: '{METADATA_KEY}' declares {dtype.itemsize:,} bytes, more than"
                f" {MAX_METADATA_BYTES:,}"
            )

    return expect


def _expected_arrays(
    metadata: Mapping[str, Any], where: str
) -> Callable[[str, tuple[int, ...], np.dtype], None]:
    """What the arrays of an agent must be, from its metadata, checked before they are read.

    A fixed network (``mlp``) holds ``params``: exactly the spec's parameters,
    as floats. A NEAT-like genome's arrays are bounded by :data:`MAX_ARRAY_BYTES`
    (checked on opening) and checked in full once read.
    """
    architecture = metadata["architecture"]
    n_params = None
    if architecture["type"] == "mlp":
        try:
            n_params = NetworkSpec.from_dict(architecture).n_params
        except EvolutionConfigError as error:
            raise AgentFileError(f"{where}: {error}") from None

    def expect(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
        if dtype.kind not in "biuf":
            raise AgentFileError(f"{where}: array {name!r} has dtype {dtype}, not numbers")
        if n_params is not None and name == "params" and shape != (n_params,):
            raise AgentFileError(
                f"{where}: 'params' must be {n_params} floats, got {dtype} of shape {shape}"
            )

    return expect


def _checked_metadata(raw: np.ndarray, where: str) -> dict[str, Any]:
    """The agent's metadata JSON, checked (format, version, architecture)."""
    try:
        metadata = json.loads(str(raw[()]))
    except (ValueError, RecursionError) as error:  # bad JSON, too deep, too many digits
        raise AgentFileError(f"{where}: metadata is not valid JSON ({error})") from None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise AgentFileError(f"{where} is not an {FORMAT} file")
    version = metadata.get("version")
    if type(version) is not int or version != FORMAT_VERSION:
        raise AgentFileError(
            f"{where} has format version {version!r}; this code reads version {FORMAT_VERSION}"
        )
    architecture = metadata.get("architecture")
    if not isinstance(architecture, dict) or not isinstance(architecture.get("type"), str):
        raise AgentFileError(f"{where}: metadata has no valid 'architecture'")
    return metadata


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

"""A :class:`~rl_baselines.jax.trainer.JaxTrainer` saved to a folder and read back, bit for bit.

A saved trainer is a folder of two files, written together atomically
(:func:`amaze.runs.folder.write_folder`: a kill leaves the old folder or the
new one, never a mix):

* ``trainer.json``: what rebuilds the trainer (:meth:`JaxTrainer.settings`:
  algorithm, robot, mazes as strings, SB3's hyperparameters, seed, ``n_envs``,
  padding, chunk size, the network spec if any) and a format tag;
* ``state.npz``: the whole training state (:func:`~rl_baselines.jax.trainer.state_arrays`:
  parameters, optimizer moments and step, the random key, the environments'
  states and observations, counters), uncompressed numpy arrays, read
  without pickling.

:func:`~rl_baselines.jax.trainer.load_trainer` builds the trainer from the
settings (read by :func:`read_settings`) and puts the arrays in (read by
:func:`read_state`), each checked by name, shape and dtype before it is
read: it continues as the saved one would have, bit for bit (a test trains
N rollouts, saves, loads, trains M and compares with N + M in one go).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.robot import as_robot
from amaze.archives import open_npz, read_npz
from amaze.errors import AmazeError
from amaze.runs.config import read_json_object
from amaze.runs.folder import settled_folder, write_folder, write_json
from amaze.validation import check_integer, check_rollout_size
from rl_baselines import RLConfigError
from rl_baselines.jax.hyperparameters import (
    MAX_CHUNK_STEPS,
    checked_hyperparameters,
    observation_size,
)
from rl_baselines.jax.spec import network_spec

__all__ = [
    "SETTINGS_FILE",
    "STATE_FILE",
    "TRAINER_FORMAT",
    "check_saved",
    "check_saved_trainers",
    "read_settings",
    "read_state",
    "save_trainer",
]

SETTINGS_FILE = "trainer.json"
STATE_FILE = "state.npz"
TRAINER_FORMAT = "jax-trainer-1"


def save_trainer(trainer: Any, folder: str | os.PathLike) -> Path:
    """Write ``trainer`` (a :class:`~rl_baselines.jax.trainer.JaxTrainer`) into ``folder``
    (replaced atomically); the folder's path.

    (The trainer is not imported here: the trainer imports this module.)
    """
    settings = {"format": TRAINER_FORMAT, **trainer.settings()}
    arrays = trainer.state_arrays()

    def fill(path: Path) -> None:
        write_json(path / SETTINGS_FILE, settings)
        with open(path / STATE_FILE, "wb") as stream:
            np.savez(stream, **arrays)
            stream.flush()
            os.fsync(stream.fileno())

    return write_folder(folder, fill)


def read_settings(folder: str | os.PathLike) -> tuple[Path, dict[str, Any]]:
    """``(folder, settings)`` of a trainer saved by :func:`save_trainer`: what rebuilds it.

    A missing or malformed ``trainer.json`` raises :class:`RLConfigError` naming it.
    """
    path = settled_folder(folder)
    settings = read_json_object(path / SETTINGS_FILE, RLConfigError, "saved trainer")
    if settings.pop("format", None) != TRAINER_FORMAT:
        raise RLConfigError(f"{path / SETTINGS_FILE} is not a saved JAX trainer ({TRAINER_FORMAT})")
    return path, settings


#: The optimizer's second moments: square roots are taken of them, so never negative.
_SECOND_MOMENTS = ("opt_state/exp_avg_sq/", "opt_state/square_avg/")


def check_state_values(name: str, value: np.ndarray) -> None:
    """A training state's array ``name`` holds values training can go on from.

    Every float array (parameters, optimizer moments, observations) is
    finite; second moments are not negative. :class:`RLConfigError` otherwise.
    """
    if value.dtype.kind != "f":
        return
    if not np.isfinite(value).all():
        raise RLConfigError(f"training state: array {name!r} holds NaN or infinity")
    if name.startswith(_SECOND_MOMENTS) and (value < 0).any():
        raise RLConfigError(f"training state: array {name!r} holds negative moments")


def check_saved(folder: str | os.PathLike) -> None:
    """Check a saved trainer as far as it can be without JAX; :class:`RLConfigError` otherwise.

    The settings are checked as the trainer checks them (algorithm, robot,
    hyperparameters with their network and rollout bounds, the rollout's
    observations, ``n_envs``, ``chunk_steps``), ``state.npz`` must be a zip
    archive of ``.npy`` entries within the absolute bounds of
    :mod:`amaze.archives`, and its
    parameters and optimizer moments hold values training can go on from
    (:func:`check_state_values`). Each array's shape against the trainer's is
    checked when it is loaded (:func:`~rl_baselines.jax.trainer.load_trainer`).
    """
    path, settings = read_settings(folder)
    where = f"{path / SETTINGS_FILE}"
    try:
        robot = as_robot(settings.get("robot"))
    except (AmazeError, TypeError) as error:
        raise RLConfigError(f"{where}: robot {settings.get('robot')!r}: {error}") from None
    hyperparameters = settings.get("hyperparameters") or {}
    if not isinstance(hyperparameters, dict):
        raise RLConfigError(f"{where}: hyperparameters {hyperparameters!r} is not an object")
    try:
        hp = checked_hyperparameters(
            settings.get("algo"),
            hyperparameters,
            robot_images=not robot.discrete_inputs,
            n_envs=settings.get("n_envs", 4),
        )
        check_rollout_size(hp.n_steps, hp.n_envs, observation_size(robot), error=RLConfigError)
        check_integer(
            "chunk_steps",
            settings.get("chunk_steps", 1),
            minimum=1,
            maximum=MAX_CHUNK_STEPS,
            error=RLConfigError,
        )
        if settings.get("network") is not None:
            network_spec(robot.to_string(), settings["network"])
    except RLConfigError as error:
        raise RLConfigError(f"{where}: {error}") from None
    state = path / STATE_FILE
    where = f"saved trainer state '{state}'"
    with open_npz(state, where, RLConfigError) as archive:
        for name in archive.names:
            if name.startswith(("params/", "opt_state/")):
                try:
                    check_state_values(name, archive.read(name))
                except RLConfigError as error:
                    raise RLConfigError(f"{state}: {error}") from None


def check_saved_trainers(run_folder: str | os.PathLike) -> None:
    """:func:`check_saved` on every trainer saved under ``run_folder`` (a JAX run's).

    What ``amaze-train --resume`` runs before it imports torch or JAX, so that
    a damaged or crafted trainer is refused at the cost of the command's start.
    """
    root = Path(run_folder)
    if root.is_dir():
        for settings in sorted(root.rglob(SETTINGS_FILE)):
            if not settings.parent.name.startswith("."):  # a folder being written (write_folder)
                check_saved(settings.parent)


def read_state(folder: Path, expected: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays of ``folder``'s ``state.npz``, each exactly like its namesake in ``expected``.

    ``expected`` is the state of the trainer rebuilt from the settings: every
    array's name, shape and dtype are checked against it before the array is
    inflated, so a damaged or crafted file can make the reader allocate no
    more than the trainer itself holds. Raises :class:`RLConfigError` naming the file.
    """
    path = folder / STATE_FILE
    where = f"saved trainer state '{path}'"

    def expect(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
        if name not in expected:
            raise RLConfigError(f"{where}: array {name!r} is not part of a trainer's state")
        model = expected[name]
        if shape != model.shape or dtype != model.dtype:
            raise RLConfigError(
                f"{where}: array {name!r} is {dtype} of shape {shape}; the trainer's is"
                f" {model.dtype} of shape {model.shape}"
            )

    budget = sum(array.nbytes for array in expected.values()) + (1 << 20)
    arrays = read_npz(
        path, where, RLConfigError, max_entry_bytes=budget, max_total_bytes=budget, expect=expect
    )
    missing = sorted(set(expected) - set(arrays))
    if missing:
        raise RLConfigError(f"{where} lacks the arrays {missing}")
    return arrays

"""A :class:`~rl_baselines.jax.trainer.JaxTrainer` saved to a folder and read back, bit for bit.

A saved trainer is a folder of two files, written together atomically
(:func:`amaze.runs.folder.write_folder`: a kill leaves the old folder or the
new one, never a mix):

* ``trainer.json``: what rebuilds the trainer (:meth:`JaxTrainer.settings`:
  algorithm, robot, mazes as strings, SB3's hyperparameters, seed, ``n_envs``,
  padding, chunk size) and a format tag;
* ``state.npz``: the whole training state (:func:`~rl_baselines.jax.trainer.state_arrays`:
  parameters, optimizer moments and step, the random key, the environments'
  states and observations, counters), uncompressed numpy arrays, read
  without pickling.

:func:`~rl_baselines.jax.trainer.load_trainer` builds the trainer from the settings
(read by :func:`read_saved`) and puts the arrays
in, each checked by name, shape and dtype: it continues as the saved one
would have, bit for bit (a test trains N rollouts, saves, loads, trains M and
compares with N + M in one go).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from amaze.runs.config import read_json_object
from amaze.runs.folder import settled_folder, write_folder, write_json
from rl_baselines import RLConfigError

__all__ = ["SETTINGS_FILE", "STATE_FILE", "TRAINER_FORMAT", "read_saved", "save_trainer"]

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


def read_saved(folder: str | os.PathLike) -> tuple[Path, dict[str, Any], dict[str, np.ndarray]]:
    """``(folder, settings, arrays)`` of a trainer saved by :func:`save_trainer`, read back.

    :func:`rl_baselines.jax.trainer.load_trainer` builds the trainer from them.
    A missing or malformed file raises :class:`RLConfigError`.
    """
    path = settled_folder(folder)
    settings = read_json_object(path / SETTINGS_FILE, RLConfigError, "saved trainer")
    if settings.pop("format", None) != TRAINER_FORMAT:
        raise RLConfigError(f"{path / SETTINGS_FILE} is not a saved JAX trainer ({TRAINER_FORMAT})")
    try:
        with np.load(path / STATE_FILE, allow_pickle=False) as stored:
            arrays = {name: stored[name] for name in stored.files}
    except (OSError, ValueError) as error:
        raise RLConfigError(f"{path / STATE_FILE} cannot be read: {error}") from None
    return path, settings, arrays

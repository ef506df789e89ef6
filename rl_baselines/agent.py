"""A trained SB3 model as a policy of the shared protocol (:mod:`amaze.evaluation.policy`).

:class:`SB3Agent` maps a batch of observations in the ``AMaze-v0`` format to a
batch of actions with ``model.predict(obs, deterministic=True)``, so SB3 agents
go through the same evaluation protocol (:func:`amaze.evaluation.protocol.evaluate`) as
evolved ones.

Files: ``save(path)`` writes SB3's zip at ``path`` (``.zip`` is appended when
missing) and a JSON file beside it (same stem, ``.json``) with the robot string
and the algorithm, which :meth:`SB3Agent.load` needs to rebuild the model.
**SB3 zips are pickle-based: load them only from trusted sources.**
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3 import A2C, PPO
from stable_baselines3.common.base_class import BaseAlgorithm

from amaze.agents.robot import Robot, as_robot
from rl_baselines import RLConfigError

__all__ = ["ALGORITHMS", "SB3Agent", "algorithm_class"]

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


def _paths(path: str | os.PathLike) -> tuple[Path, Path]:
    zip_path = Path(path)
    if zip_path.suffix != ".zip":
        zip_path = zip_path.with_name(zip_path.name + ".zip")
    return zip_path, zip_path.with_suffix(".json")


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
        return {"robot": self.robot.to_string(), "algo": self.algo, "format": "sb3-zip"}

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
        """Load an agent written by :meth:`save` (trusted files only: SB3 zips use pickle)."""
        zip_path, json_path = _paths(path)
        if not zip_path.exists():
            raise RLConfigError(f"agent file {str(zip_path)!r} does not exist")
        if not json_path.exists():
            raise RLConfigError(f"agent metadata {str(json_path)!r} does not exist")
        meta = json.loads(json_path.read_text())
        model = algorithm_class(meta["algo"]).load(zip_path, device=device)
        return cls(model, meta["robot"], meta["algo"])

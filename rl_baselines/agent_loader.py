"""The ``zip`` loader of ``amaze.agent_loaders``: an SB3 agent, checked before torch loads.

``amaze evaluate``, ``amaze run --controller`` and the other commands that
score saved agents find this loader by the file's suffix. It refuses a
hostile or damaged file with :mod:`rl_baselines.sb3_file` (no torch, no
stable-baselines3), then loads a sound one with :meth:`SB3Agent.load
<rl_baselines.agent.SB3Agent.load>`.
"""

from __future__ import annotations

import os
from typing import Any

from rl_baselines.sb3_file import agent_paths, checked_data, read_metadata, read_model_file

__all__ = ["load_agent"]


def load_agent(path: str | os.PathLike) -> Any:
    """The SB3 agent saved at ``path``, its files checked before torch is imported.

    The ``zip`` loader of ``amaze agent_loaders``: a hostile or damaged file
    raises :class:`~rl_baselines.RLConfigError` here; a sound one is loaded by
    :meth:`rl_baselines.agent.SB3Agent.load`.
    """
    zip_path, json_path = agent_paths(path)
    algo, robot = read_metadata(zip_path, json_path)
    source = f"SB3 model '{zip_path}'"
    _, data = read_model_file(zip_path, source)
    checked_data(data, algo, robot, {}, source)
    from rl_baselines.agent import SB3Agent  # torch and SB3, once the file has passed

    return SB3Agent.load(zip_path)

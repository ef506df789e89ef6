"""The gymnasium surface: ``AMaze-v0`` (:class:`MazeEnv`) and its native vector env.

``import amaze`` registers ``AMaze-v0``; ``gymnasium.make_vec(...,
vectorization_mode="vector_entry_point")`` gives :class:`MazeVectorEnv`, which
runs on the batch engine.
"""

from amaze.envs.gym_env import ENV_ID, MazeEnv, register_environments

__all__ = ["ENV_ID", "MazeEnv", "register_environments"]

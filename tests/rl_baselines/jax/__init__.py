"""Tests of rl_baselines.jax: A2C and PPO in JAX against SB3."""

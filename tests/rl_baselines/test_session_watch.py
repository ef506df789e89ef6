"""Watched sessions: an RL learner judged on other mazes than it trains on (EvalCallback's way).

Both RL learners (SB3's and JAX's) evaluate on the watch's mazes every ``every`` steps at a
rollout start (never at the session's start), keep the best by the watch's rule (the earliest
on ties) and stop once every episode there is optimal; a watch survives a save mid-session, a
damaged one is refused, and evolution's learner refuses one.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import rl_baselines.learner as learner_module
from amaze.curriculum.learner import SessionWatch, evaluation_score
from amaze.maze import rotations
from rl_baselines import RLConfigError
from rl_baselines.learner import SB3Learner, load_sb3_learner, new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

TRAINING = rotations("M0_5x5_U")
WATCHED = rotations("M3_6x6_C1")


def _sb3(seed: int = 0) -> SB3Learner:
    env = SB3VecEnv(TRAINING, "DD", 4, seed)
    model = new_sb3_model("a2c", "DD", env, seed, {})
    return SB3Learner(model, algo="a2c", robot="DD", seed=seed, n_envs=4, eval_every=20)


def _jax(seed: int = 0) -> Any:
    from rl_baselines.jax.learner import JaxLearner
    from rl_baselines.jax.trainer import JaxTrainer

    trainer = JaxTrainer("a2c", "DD", TRAINING, {}, seed=seed, n_envs=4)
    return JaxLearner(trainer, seed=seed, eval_every=20)


LEARNERS: dict[str, Callable[[], Any]] = {"sb3": _sb3, "jax": _jax}


class _Steps:
    """What a learner's session has spent when called (the watch's evaluation points)."""

    def __init__(self) -> None:
        self.learner: Any = None
        self.seen: list[int] = []

    def __call__(self) -> None:
        self.seen.append(int(self.learner.session["steps"]))


@pytest.mark.parametrize("framework", LEARNERS)
def test_a_watched_session_evaluates_on_its_watch_every_every_steps(framework: str) -> None:
    learner = LEARNERS[framework]()
    checkpoints, kept = _Steps(), _Steps()
    checkpoints.learner = kept.learner = learner
    evaluated: list[list[str]] = []
    real = learner_module.Sessions._watch_point

    def spy(self: Any, steps: int) -> bool:
        evaluated.append(list(self._watch_evaluator.maze_strings))
        return real(self, steps)

    watch = SessionWatch(tuple(WATCHED), 50, keep_best=kept)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(learner_module.Sessions, "_watch_point", spy)
        outcome = learner.train(TRAINING, 200, checkpoint=checkpoints, watch=watch)
    # A2C's rollout is 20 steps: rollout starts at 0, 20 ... 180; none evaluated at 0
    assert checkpoints.seen == [60, 120, 180]
    assert kept.seen and kept.seen[0] == 60 and set(kept.seen) <= {60, 120, 180}
    assert outcome.env_steps == 200 and not outcome.converged
    # the watch's mazes are what it plays, never the training mazes
    assert evaluated and all(m == evaluated[0] for m in evaluated)
    assert len(evaluated[0]) == len(WATCHED) and evaluated[0][0].startswith("M3_6x6")


@pytest.mark.parametrize("framework", LEARNERS)
def test_the_best_is_kept_on_strict_improvement_the_earliest_on_ties(framework: str) -> None:
    learner = LEARNERS[framework]()
    kept = _Steps()
    kept.learner = learner
    scores = iter([[0.1], [0.3], [0.3], [0.2], [0.5]])
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(learner_module, "evaluation_score", lambda rule, summary: next(scores))
        learner.train(TRAINING, 100, watch=SessionWatch(tuple(WATCHED), 20, keep_best=kept))
    # evaluations at 20, 40, 60, 80 (rollout starts) and 100 (the session's end)
    assert kept.seen == [20, 40, 100]


class _OptimalFrom:
    """Stands for the optimal R̄: every episode counts as optimal once ``learner`` has ``steps``."""

    def __init__(self, learner: Any, steps: int) -> None:
        self.learner, self.steps = learner, steps

    def __le__(self, reward: float) -> bool:
        return self.learner.session["steps"] >= self.steps


@pytest.mark.parametrize("framework", LEARNERS)
def test_a_watched_session_stops_once_every_watched_episode_is_optimal(framework: str) -> None:
    learner = LEARNERS[framework]()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(learner_module, "OPTIMAL", _OptimalFrom(learner, 100))
        outcome = learner.train(TRAINING, 1000, watch=SessionWatch(tuple(WATCHED), 50))
    assert outcome.converged
    # evaluations at 60 and 120 (rollouts of 20): converged at 120; SB3 takes one more
    # step (4 environments) before it stops
    assert outcome.env_steps == {"sb3": 124, "jax": 120}[framework]


def test_a_watched_session_saved_mid_way_continues_and_a_damaged_watch_is_refused(
    tmp_path: Path,
) -> None:
    learner = _sb3()
    saved = tmp_path / "saved"
    state: dict[str, Any] = {}

    def checkpoint() -> None:
        if not state:
            learner.save(saved)
            state.update(learner.session["watch"])

    watch = SessionWatch(tuple(WATCHED), 40)
    learner.train(TRAINING, 200, checkpoint=checkpoint, watch=watch)
    assert state["last"] == 40 and state["best_steps"] == 40 and state["every"] == 40
    again = load_sb3_learner(saved, algo="a2c", robot="DD", n_envs=4)
    assert again.session["watch"]["best"] == state["best"]
    outcome = again.train(TRAINING, 200, watch=watch)  # the same session goes on
    assert outcome.env_steps == 200
    data = json.loads((saved / "learner.json").read_text())
    data["session"]["watch"]["rule"] = "best-of-luck"
    (saved / "learner.json").write_text(json.dumps(data))
    with pytest.raises(RLConfigError, match="session watch rule 'best-of-luck'"):
        load_sb3_learner(saved, algo="a2c", robot="DD", n_envs=4)
    data["session"]["watch"].update(rule="best-eval", best=[0.5])
    (saved / "learner.json").write_text(json.dumps(data))
    with pytest.raises(RLConfigError, match=r"best \[0.5\] is not null or 2 numbers"):
        load_sb3_learner(saved, algo="a2c", robot="DD", n_envs=4)


def test_another_watch_starts_another_session(tmp_path: Path) -> None:
    learner = _sb3()
    saved = tmp_path / "saved"
    learner.train(
        TRAINING,
        200,
        checkpoint=lambda: learner.save(saved) if not saved.exists() else None,
        watch=SessionWatch(tuple(WATCHED), 40),
    )
    again = load_sb3_learner(saved, algo="a2c", robot="DD", n_envs=4)
    outcome = again.train(TRAINING, 200, watch=SessionWatch(tuple(WATCHED), 60))
    assert outcome.env_steps == 200  # a new session: the whole budget again


def test_the_rules_rank_as_named_and_bad_watches_are_refused() -> None:
    summary = {"success_rate": 0.5, "normalized_reward": -1.0}
    assert evaluation_score("best-eval", summary) == [0.5, -1.0]
    assert evaluation_score("best-eval-reward", summary) == [-1.0]
    with pytest.raises(ValueError, match="unknown evaluation rule 'luck'"):
        evaluation_score("luck", summary)
    with pytest.raises(ValueError, match="every 0"):
        SessionWatch(tuple(WATCHED), 0)
    with pytest.raises(ValueError, match="at least one maze"):
        SessionWatch((), 10)


def test_evolution_learners_refuse_a_watch() -> None:
    from evolution.learner import EvolutionConfigError, EvolutionLearner

    learner = EvolutionLearner.new("neat", {"population_size": 8}, "DD", seed=0)
    with pytest.raises(EvolutionConfigError, match="watch on other mazes is for the RL"):
        learner.train(TRAINING, 100, watch=SessionWatch(tuple(WATCHED), 50))

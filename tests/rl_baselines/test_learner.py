"""The SB3 learner: sessions in whole rollouts, early stops, files, branches, resumed sessions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

import rl_baselines.learner as learner_module
from amaze.maze import rotations
from amaze.runs.regime import RegimeConfig
from rl_baselines import RLConfigError
from rl_baselines.config import MIN_N_STEPS, TrainConfig, fitted_hyperparameters
from rl_baselines.learner import SB3Learner, load_sb3_learner, new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

TRIVIAL = rotations("M0_5x5_U")
OTHER = rotations("M3_7x7_C1")
#: A2C's default rollout: 5 steps x 4 environments.
ROLLOUT = 20


def _learner(algo: str = "a2c", seed: int = 0, eval_every: int = 20, **hyper) -> SB3Learner:
    env = SB3VecEnv(TRIVIAL, "DD", 4, seed)
    model = new_sb3_model(algo, "DD", env, seed, hyper)
    return SB3Learner(model, algo=algo, robot="DD", seed=seed, n_envs=4, eval_every=eval_every)


def _load(folder: Path, algo: str = "a2c") -> SB3Learner:
    return load_sb3_learner(folder, algo=algo, robot="DD", n_envs=4)


def _weights(learner: SB3Learner) -> list[np.ndarray]:
    return [p.detach().numpy().copy() for p in learner.model.policy.parameters()]


def _same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


OBSERVATIONS = np.random.default_rng(0).random((16, 8)).astype(np.float32)


def test_a_session_is_spent_in_whole_rollouts_never_past_its_budget() -> None:
    learner = _learner()
    calls: list[int] = []
    outcome = learner.train(TRIVIAL, 70, checkpoint=lambda: calls.append(learner.session["steps"]))
    assert outcome.env_steps == 60 and not outcome.converged and outcome.seconds > 0
    assert calls == [0, 20, 40]  # one evaluation and checkpoint per rollout start (eval_every 20)
    assert learner.model.num_timesteps == 60 and learner.session is None
    before = [p.detach().clone() for p in learner.model.policy.parameters()]
    assert learner.train(TRIVIAL, 7).env_steps == 0  # less than a rollout: none
    after = list(learner.model.policy.parameters())
    assert all(torch.equal(a, b) for a, b in zip(before, after, strict=True))
    assert learner.train(TRIVIAL, ROLLOUT).env_steps == ROLLOUT


def test_evaluations_and_checkpoints_follow_eval_every() -> None:
    learner = _learner(eval_every=50)
    calls: list[int] = []
    learner.train(TRIVIAL, 200, checkpoint=lambda: calls.append(learner.session["steps"]))
    assert calls == [0, 60, 120, 180]


class _OptimalFrom:
    """Stands for the optimal R̄: every episode counts as optimal once the model has ``steps``."""

    def __init__(self, learner: SB3Learner, steps: int) -> None:
        self.learner, self.steps = learner, steps

    def __le__(self, reward: float) -> bool:
        return self.learner.model.num_timesteps >= self.steps


def test_a_session_stops_once_every_training_episode_is_optimal(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    learner = _learner()
    monkeypatch.setattr(learner_module, "OPTIMAL", _OptimalFrom(learner, 40))
    calls: list[int] = []
    outcome = learner.train(TRIVIAL, 400, checkpoint=lambda: calls.append(1))
    # converged at the evaluation at 40; SB3 stops one step (4 envs) into the next rollout
    assert outcome.converged and outcome.env_steps == 44 and len(calls) == 3


def test_an_optimal_learner_spends_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    learner = _learner()
    before = _weights(learner)
    monkeypatch.setattr(learner_module, "OPTIMAL", -1e9)
    outcome = learner.train(TRIVIAL, 400)
    assert outcome.converged and outcome.env_steps == 0 and _same(before, _weights(learner))


@pytest.mark.parametrize("algo", ["a2c", "ppo"])
def test_save_and_load_keep_the_weights_and_the_optimiser(tmp_path: Path, algo: str) -> None:
    hyper = {"n_steps": 8, "batch_size": 16} if algo == "ppo" else {}
    learner = _learner(algo, seed=3, **hyper)
    learner.train(TRIVIAL, 64)
    learner.save(tmp_path / "l")
    assert sorted(p.name for p in (tmp_path / "l").iterdir()) == ["learner.json", "model.zip"]
    loaded = _load(tmp_path / "l", algo)
    assert loaded.seed == 3 and loaded.model.num_timesteps == learner.model.num_timesteps
    np.testing.assert_array_equal(learner.agent()(OBSERVATIONS), loaded.agent()(OBSERVATIONS))
    assert _same(_weights(learner), _weights(loaded))
    mine = learner.model.policy.optimizer.state_dict()["state"]
    theirs = loaded.model.policy.optimizer.state_dict()["state"]
    assert mine and mine.keys() == theirs.keys()
    for key in mine:
        for name, value in mine[key].items():
            assert torch.equal(torch.as_tensor(value), torch.as_tensor(theirs[key][name])), name


def test_branches_are_independent_copies_reseeded() -> None:
    parent = _learner(seed=1)
    parent.train(TRIVIAL, 40)
    start = _weights(parent)
    one, two, again = parent.branch(11), parent.branch(22), parent.branch(11)
    assert one.seed == 11 and one.model is not parent.model
    assert _same(start, _weights(one)) and _same(start, _weights(two))
    for learner in (one, two, again):
        learner.train(OTHER, 60)
    assert _same(start, _weights(parent))  # the parent is untouched by its branches
    assert not _same(_weights(one), start)
    assert not _same(_weights(one), _weights(two))  # other seeds, other draws
    assert _same(_weights(one), _weights(again))  # the same seed, the same draws
    assert parent.model.policy.optimizer is not one.model.policy.optimizer


class _Killed(Exception):
    pass


def test_a_learner_saved_mid_session_continues_its_session(tmp_path: Path) -> None:
    learner = _learner(seed=4)
    folder = tmp_path / "checkpoint"
    calls = 0

    def checkpoint() -> None:
        nonlocal calls
        calls += 1
        if calls == 3:  # saved at the start of the third rollout (40 steps), then killed
            learner.save(folder)
            raise _Killed

    with pytest.raises(_Killed):
        learner.train(TRIVIAL, 100, checkpoint=checkpoint)
    loaded = _load(folder)
    assert loaded.session is not None and loaded.session["steps"] == 40
    assert loaded.model.num_timesteps == 40
    outcome = loaded.train(TRIVIAL, 100)
    assert outcome.env_steps == 100 and loaded.model.num_timesteps == 100
    # another session (other mazes or budget) starts from zero
    assert _load(folder).train(OTHER, 100).env_steps == 100


def test_a_session_on_seconds_alone_ends_when_they_are_spent(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    learner = _learner()
    monkeypatch.setattr(learner_module, "OPTIMAL", 2.0)  # never optimal: only the clock stops it
    states: list[dict] = []
    outcome = learner.train(
        TRIVIAL, None, budget_seconds=1.0, checkpoint=lambda: states.append(dict(learner.session))
    )
    assert not outcome.converged and outcome.env_steps > 0
    assert 1.0 <= outcome.seconds < 31  # stopped at a step once a second was spent
    assert learner.model.num_timesteps == outcome.env_steps and learner.session is None
    assert states and all(s["budget"] is None and s["budget_seconds"] == 1.0 for s in states)


def test_with_both_budgets_a_session_ends_at_the_first() -> None:
    learner = _learner()
    assert learner.train(TRIVIAL, 60, budget_seconds=600.0).env_steps == 60
    before = _weights(learner)
    spent = learner.train(TRIVIAL, 60, budget_seconds=0.0)  # no time: not even one rollout
    assert spent.env_steps == 0 and _same(before, _weights(learner))


@pytest.mark.parametrize(
    ("steps", "seconds", "words"),
    [
        (None, None, "needs budget_steps or budget_seconds"),
        (None, -1.0, "budget_seconds -1.0"),
        (-5, None, "budget_steps -5"),
        (None, "x", "budget_seconds 'x'"),
    ],
)
def test_a_session_without_a_valid_budget_is_refused(steps, seconds, words: str) -> None:
    with pytest.raises(RLConfigError, match=words):
        _learner().train(TRIVIAL, steps, budget_seconds=seconds)


def test_a_session_on_seconds_saved_mid_way_continues_with_the_same_budgets(
    tmp_path: Path,
) -> None:
    learner = _learner(seed=5)
    folder = tmp_path / "checkpoint"
    calls = 0

    def checkpoint() -> None:
        nonlocal calls
        calls += 1
        if calls == 3:  # the start of the third rollout, 40 steps in
            learner.save(folder)
            raise _Killed

    with pytest.raises(_Killed):
        learner.train(TRIVIAL, 100, budget_seconds=60.0, checkpoint=checkpoint)
    saved = json.loads((folder / "learner.json").read_text())["session"]
    assert (saved["budget"], saved["budget_seconds"], saved["steps"]) == (100, 60.0, 40)
    assert saved["seconds"] > 0
    outcome = _load(folder).train(TRIVIAL, 100, budget_seconds=60.0)
    # the same session: its steps and seconds go on from the save
    assert outcome.env_steps == 100 and outcome.seconds >= saved["seconds"]
    # another seconds budget is another session, from zero
    other = _load(folder)
    assert other.train(TRIVIAL, 100, budget_seconds=61.0).env_steps == 100
    assert other.model.num_timesteps == 140


def test_a_session_saved_before_seconds_budgets_continues(tmp_path: Path) -> None:
    learner = _learner(seed=6)
    folder = tmp_path / "checkpoint"

    def checkpoint() -> None:
        if learner.session["steps"] == 40:
            learner.save(folder)
            raise _Killed

    with pytest.raises(_Killed):
        learner.train(TRIVIAL, 100, checkpoint=checkpoint)
    data = json.loads((folder / "learner.json").read_text())
    del data["session"]["budget_seconds"]  # as written before seconds budgets existed
    (folder / "learner.json").write_text(json.dumps(data))
    loaded = _load(folder)
    assert loaded.session is not None and loaded.session["budget_seconds"] is None
    assert loaded.train(TRIVIAL, 100).env_steps == 100 and loaded.model.num_timesteps == 100


def test_fitted_rollouts_fit_the_first_allowance() -> None:
    def fitted(**fields) -> dict:
        """The rollout fitted (and the hyperparameters given), of all those recorded."""
        used = fitted_hyperparameters(TrainConfig.from_dict({"regime": "edhucat", **fields}))
        shown = ("n_steps", "batch_size", *fields.get("hyperparameters", {}))
        return {name: used[name] for name in shown if name in used}

    common = {"curator": "random", "stages": 3, "branches": 2, "budget_steps": 30_000}
    assert fitted(algo="ppo", **common) == {"n_steps": 1024, "batch_size": 64}
    assert fitted(algo="a2c", **common) == {"n_steps": 5}  # A2C's default fits
    assert fitted(algo="ppo", **{**common, "budget_steps": 600}) == {
        "n_steps": 16,  # 600 // 6 = 100 steps: 16 x 4 environments
        "batch_size": 64,
    }
    tiny = {**common, "budget_steps": 120}
    assert fitted(algo="ppo", **tiny) == {"n_steps": MIN_N_STEPS, "batch_size": 4 * MIN_N_STEPS}
    mine = {"n_steps": 4096, "learning_rate": 0.01}
    assert fitted(algo="ppo", hyperparameters=mine, **common) == {**mine, "batch_size": 64}
    assert fitted(algo="ppo", hyperparameters={"batch_size": 7}, **common)["batch_size"] == 7
    # a seconds budget alone has no allowance in steps: SB3's defaults stay
    seconds = {**common, "budget_steps": None, "budget_seconds": 60}
    assert fitted(algo="ppo", **seconds) == {"n_steps": 2048, "batch_size": 64}
    assert fitted(algo="a2c", **seconds) == {"n_steps": 5}
    both = {**tiny, "budget_seconds": 60}  # with both, the steps allowance still fits it
    assert fitted(algo="ppo", **both) == {"n_steps": MIN_N_STEPS, "batch_size": 4 * MIN_N_STEPS}
    assert isinstance(TrainConfig(), RegimeConfig)


@pytest.mark.parametrize(
    ("damage", "words"),
    [
        (lambda f: (f / "learner.json").write_text("{"), "is not JSON"),
        (lambda f: (f / "learner.json").unlink(), "does not exist"),
        (lambda f: (f / "model.zip").unlink(), "is missing"),
        (lambda f: (f / "model.zip").write_bytes(b"x"), "model.zip"),
        (lambda f: _edit(f, algo="ppo"), "algo 'ppo'"),
        (lambda f: _edit(f, seed=-1), "seed -1"),
        (lambda f: _edit(f, num_timesteps=7), "different saves"),
        (lambda f: _edit(f, log_name="../x"), "log_name"),
        (lambda f: _edit(f, session={"mazes": ["nope"]}), "session mazes"),
        (lambda f: _edit(f, session=3), "session 3"),
        (lambda f: _edit_session(f, budget_seconds=-2), "session budget_seconds -2"),
        (lambda f: _edit_session(f, budget_seconds="soon"), "session budget_seconds 'soon'"),
        (lambda f: _edit_session(f, budget=None, budget_seconds=None), "session has no budget"),
    ],
)
def test_a_damaged_learner_is_refused_naming_the_file(tmp_path: Path, damage, words: str) -> None:
    _learner().save(tmp_path / "l")
    damage(tmp_path / "l")
    with pytest.raises(RLConfigError, match=words) as raised:
        _load(tmp_path / "l")
    assert str(tmp_path / "l") in str(raised.value)


def _edit(folder: Path, **changes: object) -> None:
    path = folder / "learner.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))


def _edit_session(folder: Path, **changes: object) -> None:
    """Give ``learner.json`` a session (a valid one, but for ``changes``)."""
    session = {
        "mazes": TRIVIAL,
        "budget": 100,
        "budget_seconds": 5.0,
        "steps": 0,
        "seconds": 0.0,
        "converged": False,
        "last_eval": None,
    }
    _edit(folder, session={**session, **changes})

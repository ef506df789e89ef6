"""The config of an ``amaze-train`` run (:class:`TrainConfig`) and its hyperparameter checks.

:class:`TrainConfig` is a :class:`~amaze.runs.regime.RegimeConfig`:
``regime`` is ``direct`` (:class:`rl_baselines.train.SB3Run`), ``interpolation``,
``edhucat`` or ``edens`` (the curriculum loop, :class:`rl_baselines.curriculum.SB3CurriculumRun`),
with ``curator``, ``stages``, ``branches`` and ``target`` for the curricula, or
``coevolution`` (:class:`rl_baselines.coevolution.SB3CoevolutionRun`, or with the jax framework
:class:`rl_baselines.jax.coevolution.JaxCoevolutionRun`).

**Rollouts of a curriculum** (:func:`fitted_hyperparameters`). A curriculum
gives each branch ``budget_steps / (K * S)`` steps (the paper's split), which
with small budgets is less than one default rollout (PPO: 2048 steps x
``n_envs``). When the user did not set ``n_steps``, a curriculum run whose
default rollout does not fit the first branch's allowance uses the largest
power of two ``n_steps`` with ``n_steps * n_envs`` within it (at least
:data:`MIN_N_STEPS`); PPO's ``batch_size``, when not set either, becomes the
largest power of two that divides the rollout, at most SB3's default. The
choice is made once from the config (so a resumed run makes the same one),
holds for the whole run, and is recorded in ``summary.json``
(``hyperparameters_used``). Hyperparameters the user set are never changed.
A run on a seconds budget alone (``budget_steps`` null) has no step allowance
to fit a rollout to: it keeps SB3's default rollout (set ``n_steps`` for short
budgets).

**Budgets.** ``budget_steps`` env steps and/or ``budget_seconds`` wall-clock
seconds of training, in every regime; with both, training stops at whichever
is reached first. ``--budget-seconds`` alone on the command line is a pure
time budget (no step limit). Where a run on a seconds budget stops depends on
the machine's speed, so it neither replays nor resumes bit-identically.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from amaze.agents.robot import as_robot
from amaze.curriculum.learner import EVALUATION_RULES
from amaze.curriculum.maze_population import MazePopulationConfig
from amaze.curriculum.regimes import REGIMES, branch_allowance
from amaze.evaluation.suite import PAPER_EVALUATION_MAZE
from amaze.runs.config import config_from_dict, option
from amaze.runs.regime import RegimeConfig
from amaze.validation import check_integer, check_number, closest
from rl_baselines import RLConfigError
from rl_baselines.jax.hyperparameters import SB3_DEFAULTS
from rl_baselines.presets import PRESETS, preset_values
from rl_baselines.protocols import (
    PROTOCOL_REGIMES,
    PROTOCOLS,
    protocol_values,
    with_learning_rate,
)

__all__ = [
    "FRAMEWORKS",
    "MIN_N_STEPS",
    "TrainConfig",
    "check_rollout_fits",
    "fitted_hyperparameters",
    "used_hyperparameters",
]

#: Evaluations per stage on an interpolation's evaluation series (the paper's scripts: 100).
DEFAULT_STAGE_EVALUATIONS = 100
#: Most evaluations per stage.
MAX_STAGE_EVALUATIONS = 10_000
#: The fewest steps per environment a fitted rollout has.
MIN_N_STEPS = 8
#: What trains the agent: stable-baselines3, or its A2C/PPO compiled with JAX
#: (:mod:`rl_baselines.jax`).
FRAMEWORKS = ("sb3", "jax")


@dataclass
class TrainConfig(RegimeConfig):
    """Everything that defines a training run (stored as ``config.json``).

    The budget is ``budget_steps`` env steps and/or ``budget_seconds``
    seconds of training (either may be ``None``, not both); a run stops at
    whichever it reaches first. A config file without ``budget_seconds`` (one
    written before it existed) is a steps budget, as it was.
    """

    error = RLConfigError
    options_field = "hyperparameters"
    #: every regime; edens-populations, whose alternatives copy the learner every epoch,
    #: with the jax framework only (its training state is data; SB3's model is not)
    supported_regimes = REGIMES
    agent_rules = ("final", *EVALUATION_RULES)
    #: An open-ended curriculum's epoch: the paper's 100 k steps a branch at 3 M steps, K = 3.
    default_epochs = 10
    default_eval_mazes = (PAPER_EVALUATION_MAZE,)

    algo: str = option("ppo", "SB3 algorithm", choices=("a2c", "ppo"))
    framework: str = option(
        "sb3",
        "what trains the agent: sb3 (stable-baselines3, torch) or jax (the same A2C/PPO"
        " compiled with JAX: faster, resumes bit for bit, no TensorBoard)",
        choices=FRAMEWORKS,
    )
    budget_steps: int | None = option(
        3_000_000, "environment steps (none when --budget-seconds is given alone)"
    )
    budget_seconds: float | None = option(
        None,
        "wall-clock seconds of training; where such a run stops depends on the machine's"
        " speed, so it neither replays nor resumes bit for bit",
    )
    eval_every: int = option(50_000, "environment steps between evaluations and checkpoints")
    n_envs: int = option(4, "environments stepped together (a multiple of 4: one per rotation)")
    tensorboard: bool | None = option(
        None,
        "write TensorBoard logs to OUT/tensorboard (default: on with --framework sb3;"
        " the jax framework writes none)",
    )
    hyperparameters: dict[str, Any] = option(
        default_factory=dict,
        help="SB3 hyperparameters overriding SB3's defaults",
        command_line=False,
    )
    network: dict[str, Any] | None = option(
        None,
        "framework jax: evolution's network spec (hidden, activation, pool, symmetry, filters,"
        " stride) instead"
        " of SB3's policy; the agent is saved as an evolved agent's file (agent.npz)",
        command_line=False,
    )
    progress_reward: float = option(
        0.0,
        "framework jax, continuous robots: reward for reaching cells further along each"
        " maze's solution, an episode gaining this times its path progress times the maze's"
        " finish reward (0: AMaze's reward alone; evaluations score AMaze's)",
    )
    agent_rule: str | None = option(
        None,
        "which agent the run hands over: final (the agent when training stops), best-eval"
        " (the best on eval_mazes, by success rate then R̄), best-eval-reward (the best by R̄"
        " alone, never the untrained one: SB3's EvalCallback); in interpolation with"
        " --stage-eval-target, the last stage's best on its evaluation series (default: final)",
        metavar="RULE",
        regimes=("direct", "interpolation"),
    )
    stage_eval_target: str | None = option(
        None,
        "interpolation: the end maze of an evaluation series, interpolated as the target is;"
        " each stage is evaluated on the same stage of it (4 rotations), stops once every"
        " episode there is optimal, and keeps its best agent (the paper's scripts; eval_every"
        " then plays no part); default: none, stages stop on their own mazes",
        metavar="MAZE",
        regimes=("interpolation",),
    )
    stage_evaluations: int | None = option(
        None,
        "interpolation with --stage-eval-target: evaluations per stage, every stage"
        " allowance / N env steps (default: 100, the paper's scripts)",
        metavar="N",
        regimes=("interpolation",),
    )
    protocol: str | None = option(
        None,
        "a named protocol filling the options it names that the config does not set:"
        " paper-code (the paper's training scripts as they ran; docs/trainers/rl.md)",
        choices=PROTOCOLS,
        regimes=PROTOCOL_REGIMES,
    )

    preset: str | None = option(
        None,
        "a named setting of the jax framework filling the options it names that the config"
        " does not set: fast (many environments, large minibatches, the shared 16-unit"
        " symmetric network; docs/trainers/rl.md)",
        choices=tuple(PRESETS),
    )

    @classmethod
    def from_dict(cls, data: Any) -> TrainConfig:
        """A checked config from a JSON object; a ``protocol`` fills only the keys it lacks."""
        config = config_from_dict(cls, data, cls.error)
        config._given = frozenset(data)
        return config.validate()

    def _apply_protocol(self) -> None:
        """Fill the options the ``protocol`` names (:mod:`rl_baselines.protocols`), if unset.

        Unset means absent from the JSON object the config was read from
        (:meth:`from_dict`); a config built in Python counts a field at its
        default as unset. Applied once: a validated config records every value.
        """
        if self.protocol is None or getattr(self, "_protocol_applied", False):
            return
        if self.regime not in PROTOCOL_REGIMES:
            return  # refused with the options of other regimes (refuse_options_without_effect)
        try:
            values = protocol_values(
                self.protocol, self.regime, self.budget_steps, self._given_fields()
            )
        except ValueError as problem:
            raise RLConfigError(f"protocol (--protocol): {problem}") from None
        for name, value in values.items():
            setattr(self, name, value)
        if isinstance(self.hyperparameters, dict):
            self.hyperparameters = with_learning_rate(self.hyperparameters)
        self._protocol_applied = True

    def _given_fields(self) -> set[str]:
        """The fields the config was given: the keys of its JSON object (:meth:`from_dict`);
        for a config built in Python, the fields away from their default."""
        given = getattr(self, "_given", None)
        if given is not None:
            return set(given)
        return {
            f.name
            for f in dataclasses.fields(self)
            if getattr(self, f.name)
            != (f.default if f.default_factory is dataclasses.MISSING else f.default_factory())
        }

    def _apply_preset(self) -> None:
        """Fill the fields the ``preset`` names (:mod:`rl_baselines.presets`), if unset.

        ``hyperparameters`` key by key. A preset and the paper's protocol are
        two settings of the same options: refused together. Applied once.
        """
        if self.preset is None or getattr(self, "_preset_applied", False):
            return
        if self.protocol is not None:
            raise RLConfigError(
                f"preset {self.preset!r} with protocol {self.protocol!r}: the protocol runs the"
                " paper's setting, the preset another one (give one of them)"
            )
        if not isinstance(self.hyperparameters, dict):
            raise RLConfigError(f"hyperparameters {self.hyperparameters!r} is not a JSON object")
        framework = PRESETS.get(self.preset, {}).get("framework")
        if "framework" in self._given_fields() and framework not in (None, self.framework):
            raise RLConfigError(
                f"preset {self.preset!r} with framework {self.framework!r}: the preset is a"
                f" setting of framework {framework} (give that framework, or none)"
            )
        try:
            values = preset_values(
                self.preset, str(self.algo).lower(), self._given_fields(), self.hyperparameters
            )
        except ValueError as problem:
            raise RLConfigError(f"preset (--preset): {problem}") from None
        for name, value in values.items():
            setattr(self, name, value)
        self._preset_applied = True

    def validate(self) -> TrainConfig:
        """Check every field; raise :class:`RLConfigError` naming the bad value."""
        if self.protocol is not None and self.protocol not in PROTOCOLS:
            raise RLConfigError(
                f"unknown protocol {self.protocol!r} (choose from {', '.join(PROTOCOLS)})"
            )
        self._apply_protocol()
        self._apply_preset()
        if not isinstance(self.algo, str) or self.algo.lower() not in SB3_DEFAULTS:
            raise RLConfigError(
                f"unknown algorithm {self.algo!r} (choose from {', '.join(SB3_DEFAULTS)})"
            )
        self.algo = self.algo.lower()
        self._check_envs()  # before the regime's checks: a coevolution batch follows from n_envs
        super().validate()
        self._check_budget()
        if self.tensorboard is None:
            self.tensorboard = self.framework == "sb3"
        if not isinstance(self.tensorboard, bool):
            raise RLConfigError(f"tensorboard {self.tensorboard!r} is not true or false")
        if self.regime == "direct" and not self.eval_mazes:
            raise RLConfigError(
                "eval_mazes is empty: a direct RL run evaluates, checkpoints and logs its"
                " progress at its evaluations"
            )
        if not isinstance(self.hyperparameters, dict):
            raise RLConfigError(f"hyperparameters {self.hyperparameters!r} is not a JSON object")
        check_hyperparameters(self.algo, self.hyperparameters)
        self.hyperparameters = used_hyperparameters(self)
        self._check_framework()
        self._check_stage_evaluation()
        return self

    def _check_stage_evaluation(self) -> None:
        """An interpolation's evaluation series, its cadence and the agent rule it allows."""
        if self.regime != "interpolation":
            return
        if self.stage_eval_target is None:
            for name in ("stage_evaluations", "agent_rule"):
                if getattr(self, name) is not None:
                    flag = name.replace("_", "-")
                    raise RLConfigError(
                        f"{name} (--{flag}) {getattr(self, name)!r} needs an evaluation series"
                        " in the interpolation regime (--stage-eval-target MAZE)"
                    )
            return
        self.stage_eval_target = self._maze("stage_eval_target", self.stage_eval_target)
        if self.budget_steps is None:
            raise RLConfigError(
                "stage_eval_target needs budget_steps: a stage's evaluations are spaced by its"
                " allowance of env steps"
            )
        if self.stage_evaluations is None:
            self.stage_evaluations = DEFAULT_STAGE_EVALUATIONS
        self.stage_evaluations = check_integer(
            "stage_evaluations", self.stage_evaluations, minimum=1, maximum=MAX_STAGE_EVALUATIONS,
            error=RLConfigError,
        )  # fmt: skip
        if self.agent_rule is None:
            self.agent_rule = "final"
        if self.agent_rule not in self.agent_rules:
            raise RLConfigError(
                f"agent_rule {self.agent_rule!r} is not one of {', '.join(self.agent_rules)}"
            )
        if self.agent_rule != "final" and self.final_training:
            raise RLConfigError(
                f"agent_rule {self.agent_rule!r} hands over the last stage's best agent, which"
                " final_training would train further: give --no-final-training"
            )

    def _check_framework(self) -> None:
        """The jax framework: its regimes, its robots, no TensorBoard, its hyperparameters.

        What the JAX learners do not implement is refused, never ignored: robots with
        continuous actions without a network spec (SB3's policy is not offered for
        them, :mod:`rl_baselines.jax.spec`), TensorBoard logs, and SB3 hyperparameters they
        lack or values they do not take
        (:func:`~rl_baselines.jax.hyperparameters.checked_hyperparameters`:
        ``use_sde``, schedules, other rollout buffers...).
        """
        if self.framework not in FRAMEWORKS:
            raise RLConfigError(
                f"framework {self.framework!r} is unknown (choose from {', '.join(FRAMEWORKS)})"
            )
        self.progress_reward = check_number(
            "progress_reward", self.progress_reward, minimum=0.0, error=RLConfigError
        )
        if self.progress_reward and self.framework != "jax":
            raise RLConfigError(
                f"progress_reward {self.progress_reward!r} has no effect with framework"
                f" {self.framework}: the JAX environment of continuous robots pays it"
                " (give framework jax)"
            )
        if self.framework != "jax":
            if self.regime == "edens-populations":
                raise RLConfigError(
                    f"regime edens-populations with framework {self.framework}: its alternatives"
                    " copy the learner every epoch, which only the jax framework's training"
                    " state allows (give framework jax)"
                )
            if self.network is not None:
                raise RLConfigError(
                    f"network {self.network!r} has no effect with framework {self.framework}:"
                    " SB3 trains its own policies (give framework jax)"
                )
            return
        robot = as_robot(self.robot)
        if self.progress_reward and robot.discrete_outputs:
            raise RLConfigError(
                f"progress_reward {self.progress_reward!r} has no effect with robot {self.robot}:"
                " it rewards continuous robots (CC...) only"
            )
        if not robot.discrete_outputs and self.network is None:
            raise RLConfigError(
                f"robot {self.robot} has continuous actions: framework jax trains them with a"
                ' network spec (give the config a network, e.g. {"hidden": [16],'
                ' "symmetry": "rotations"})'
            )
        if self.tensorboard:
            raise RLConfigError(
                "tensorboard (--tensorboard) True has no effect with framework jax: it writes"
                " no TensorBoard logs (progress.csv and evaluations.csv hold its evaluations)"
            )
        from rl_baselines.jax.hyperparameters import checked_hyperparameters

        try:
            checked_hyperparameters(
                self.algo,
                self.hyperparameters,
                robot_images=not robot.discrete_inputs,
                n_envs=self.n_envs,
            )
        except RLConfigError as problem:
            raise RLConfigError(f"framework jax: {problem}") from None
        if self.network is not None:
            from rl_baselines.jax.spec import network_spec

            if self.hyperparameters.get("policy_kwargs"):
                raise RLConfigError(
                    "hyperparameter 'policy_kwargs' with a network: the network gives the"
                    " policy's layers (give one of them)"
                )
            network_spec(self.robot, self.network)

    def _check_envs(self) -> None:
        """``eval_every`` and ``n_envs`` are integers >= 1, ``n_envs`` a multiple of 4."""
        for name in ("eval_every", "n_envs"):
            value = check_integer(name, getattr(self, name), minimum=1, error=RLConfigError)
            setattr(self, name, value)
        if self.n_envs % 4:
            raise RLConfigError(f"n_envs {self.n_envs} is not a multiple of 4 (one per rotation)")

    def _check_budget(self) -> None:
        """``budget_steps`` (an integer >= 1) and/or ``budget_seconds`` (a number > 0)."""
        if self.budget_steps is not None:
            self.budget_steps = check_integer(
                "budget_steps", self.budget_steps, minimum=1, error=RLConfigError
            )
        if self.budget_seconds is not None:
            self.budget_seconds = check_number(
                "budget_seconds",
                self.budget_seconds,
                minimum=0,
                strict_minimum=True,
                error=RLConfigError,
            )
        if self.budget_steps is None and self.budget_seconds is None:
            raise RLConfigError(
                f"budget_steps {self.budget_steps!r} and budget_seconds"
                f" {self.budget_seconds!r}: a run needs at least one budget"
            )

    @classmethod
    def adapt_config_file(cls, loaded: dict[str, Any]) -> dict[str, Any]:
        """An rl-zoo3 hyperparameter file (``AMaze-v0: {n_timesteps: ..., ...}``) as a config.

        A file whose one key is not a config key (an environment id) holding a
        mapping is read as rl-zoo3 writes them: ``n_timesteps`` is
        ``budget_steps``, ``n_envs`` is ``n_envs``, ``policy`` must be the one
        the robot uses (``MlpPolicy``; ``CnnPolicy`` for image robots) and is
        dropped, the rest are SB3 hyperparameters. rl-zoo3's entries that name
        code (``env_wrapper``, ``callback``, ``frame_stack``...) and Python
        strings it evaluates (``policy_kwargs: "dict(...)"``) are refused:
        give the values themselves.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        if len(loaded) != 1:
            return loaded
        ((key, table),) = loaded.items()
        if key in names or not isinstance(table, dict):
            return loaded
        table = dict(table)
        config: dict[str, Any] = {}
        if "n_timesteps" in table:
            steps = table.pop("n_timesteps")
            number = isinstance(steps, int | float) and not isinstance(steps, bool)
            config["budget_steps"] = int(steps) if number and float(steps).is_integer() else steps
        if "n_envs" in table:
            config["n_envs"] = table.pop("n_envs")
        policy = table.pop("policy", None)
        if policy not in (None, "MlpPolicy", "CnnPolicy"):
            raise RLConfigError(f"rl-zoo3 policy {policy!r}: the trainer uses MlpPolicy/CnnPolicy")
        for name in _ZOO_CODE:
            if name in table:
                raise RLConfigError(
                    f"rl-zoo3 entry {name!r} of {key!r} names code, which a config cannot run"
                )
        for name, value in table.items():
            if isinstance(value, str) and name not in ("device",):
                raise RLConfigError(
                    f"rl-zoo3 hyperparameter {name!r} is the string {value!r}: rl-zoo3 evaluates"
                    " such strings as Python; give the value itself"
                )
        return {**config, "hyperparameters": table}

    def coevolution_defaults(self) -> dict[str, Any]:
        """One environment per rotation of each batch maze: ``batch`` is ``n_envs / 4``.

        A batch larger than the population's default capacity raises that
        default to hold it (a capacity the config gives is its own).
        """
        batch = self.n_envs // 4
        defaults: dict[str, Any] = {"batch": batch}
        if batch > MazePopulationConfig.capacity:
            defaults["capacity"] = batch
        return defaults

    def check_coevolution_options(self, options: MazePopulationConfig) -> None:
        """The batch fills the environments: ``n_envs`` is 4 x ``batch``."""
        if options.batch * 4 != self.n_envs:
            raise RLConfigError(
                f"coevolution batch {options.batch!r} needs n_envs = 4 x batch (one environment"
                f" per rotation of each maze), not {self.n_envs}"
            )


#: rl-zoo3 entries that name code (wrappers, callbacks): never taken from a file.
_ZOO_CODE = (
    "env_wrapper", "callback", "frame_stack", "normalize", "vec_env_wrapper", "env_kwargs",
    "eval_env_kwargs", "normalize_kwargs",
)  # fmt: skip
#: Hyperparameters the trainer sets itself.
_RESERVED = frozenset(
    {"policy", "env", "seed", "device", "verbose", "tensorboard_log", "_init_setup_model"}
)
#: Integer hyperparameters that SB3 needs to be at least 1.
_POSITIVE = frozenset({"n_steps", "batch_size", "n_epochs"})


def sb3_defaults(algo: str) -> dict[str, Any]:
    """The keyword arguments of the SB3 algorithm that a config may set, and their defaults.

    SB3's own (:data:`rl_baselines.jax.hyperparameters.SB3_DEFAULTS`, checked
    against SB3's signatures by a test), written out so that reading and
    checking a config imports neither torch nor SB3.
    """
    return dict(SB3_DEFAULTS[algo])


def check_hyperparameters(algo: str, hyperparameters: dict[str, Any]) -> None:
    """Each hyperparameter is one of the algorithm's, of the type of its SB3 default.

    SB3 checks some values with ``assert`` and others only when training
    starts (a string learning rate fails deep inside torch); checking the
    types here gives one clear error, naming the value, before the run starts.
    """
    defaults = sb3_defaults(algo)
    for name, value in hyperparameters.items():
        what = f"hyperparameter {name!r}"
        if name in _RESERVED:
            raise RLConfigError(f"{what} is set by the trainer")
        if name not in defaults:
            raise RLConfigError(f"{what} is not one of {algo.upper()}'s{closest(name, defaults)}")
        default = defaults[name]
        if name.endswith("_class"):
            raise RLConfigError(f"{what} names a class, which a config file cannot give")
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise RLConfigError(f"{what} {value!r} is not true or false")
        elif isinstance(default, int):
            check_integer(
                what, value, minimum=1 if name in _POSITIVE else None, error=RLConfigError
            )
        elif isinstance(default, float) or (default is None and not name.endswith("kwargs")):
            if value is not None or default is not None:
                check_number(what, value, error=RLConfigError)
        elif default is None and value is not None and not isinstance(value, dict):
            raise RLConfigError(f"{what} {value!r} is not a JSON object")


def used_hyperparameters(config: TrainConfig) -> dict[str, Any]:
    """Every SB3 hyperparameter the run uses: SB3's defaults, the config's, a curriculum's fit.

    What ``config.json`` records, as rl-zoo3 does, so that a run says what ran
    (and a later SB3 with other defaults cannot change it). The ones the
    trainer sets itself (seed, device, the policy class...) are left out;
    a hybrid robot's CNN is added to ``policy_kwargs`` when the model is built.
    Filling them in twice gives the same: a curriculum's fitted rollout,
    recorded, is then the config's own.
    """
    used = {
        name: value
        for name, value in sb3_defaults(config.algo).items()
        if not name.endswith("_class")
    }
    used.update(config.hyperparameters)
    if config.is_curriculum:
        used.update(fitted_hyperparameters(config))
    return used


def check_rollout_fits(config: TrainConfig, rollout: int, unit: str) -> None:
    """Refuse a steps budget that cannot pay one rollout: the run would learn nothing.

    ``unit`` says how the run spends rollouts (``"learns in whole rollouts"``).
    """
    if config.budget_steps is not None and config.budget_steps < rollout:
        raise RLConfigError(
            f"budget_steps {config.budget_steps} cannot pay one rollout ({rollout} steps:"
            f" n_steps {rollout // config.n_envs} x n_envs {config.n_envs}): the run {unit};"
            " give a larger budget, or a smaller n_steps in hyperparameters"
        )


def fitted_hyperparameters(config: TrainConfig) -> dict[str, Any]:
    """The hyperparameters a curriculum run gives SB3 (see the module docstring).

    The user's, with ``n_steps`` (and PPO's ``batch_size``) fitted to the
    first branch's allowance when the user did not set them and SB3's
    default rollout does not fit it; ``n_steps`` and ``batch_size`` (PPO)
    are always present, so the result says what ran. Without ``budget_steps``
    (a seconds budget alone) there is no allowance in steps: SB3's defaults
    stay.
    """
    c = config
    assert c.stages is not None and c.branches is not None
    defaults = sb3_defaults(c.algo)
    used = dict(c.hyperparameters)
    allowance = None
    if c.budget_steps is not None:
        allowance = branch_allowance(c.budget_steps, 0, 0, c.stages, c.branches, c.epochs)
    fitted = False
    if "n_steps" not in used:
        n_steps = int(defaults["n_steps"])
        if allowance is not None and n_steps * c.n_envs > allowance:
            fits = max(allowance // c.n_envs, 1)
            n_steps = min(n_steps, max(MIN_N_STEPS, 1 << (fits.bit_length() - 1)))
            fitted = True
        used["n_steps"] = n_steps
    if c.algo == "ppo" and "batch_size" not in used:
        batch_size = int(defaults["batch_size"])
        if fitted:
            batch_size = math.gcd(used["n_steps"] * c.n_envs, batch_size)
        used["batch_size"] = batch_size
    return used

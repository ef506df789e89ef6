"""Teach a network the oracle's actions: can it drive this robot, and how well?

Evolution searches a :class:`~evolution.networks.NetworkSpec`'s parameters for a
policy; when it finds none, the network may be unable to represent one (too
few units, a pooled image too coarse), or the search may not reach it. This
module tells the two apart: DAgger (Ross, Gordon and Bagnell, 2011) fits the
network, by gradient descent in torch, to the actions of
:class:`~amaze.evaluation.controllers.OracleController` (which knows the
maze's solution and the robot's position; the network sees only its
observation), or of another teacher (below), on the states the network itself
reaches. Iteration ``i`` drives the robots with the teacher's action (the
oracle's by default) with probability ``0.5 ** i`` and the network's
otherwise, labels every observation with the teacher's action, and fits the
network on all observations so far (the newest ``max_samples``): continuous
robots by the squared error of the accelerations, discrete ones by the
cross-entropy of the direction scores.
Iteration ``i``'s Adam steps take ``learning_rate * learning_rate_decay ** i``
(a decay under 1 lets the late iterations, where the network drives itself,
settle instead of moving as far as the first). Given validation mazes, each
iteration's network is scored on them (success rate and path progress, one
episode each), and ``keep = "best"`` hands over the network with the highest
success, then path progress, instead of the last: late iterations can lose
what earlier ones taught (measured on CC7, docs/robots.md). ``keep =
"average"`` hands over the mean of the parameters of the iterations from
``average_from`` on (by default the second half), as stochastic weight
averaging does (Izmailov et al., 2018): at a constant learning rate the late
iterations scatter round a region that fits the aggregated data, and their
mean sits nearer its middle than any one of them. With validation mazes the
running mean is scored after each of those iterations too.
The parameters come back in the spec's own layout, so the taught network is
an ordinary agent (:func:`evolution.agent_file.save_network_agent`) scored
by the usual evaluators.

Three uses. A capacity check: a network that cannot be taught to drive cannot
be evolved to. A trainer with a privileged teacher: the teacher knows
each maze's solution while teaching, the taught network sees only its own
inputs, so its results are reported apart from those of RL and evolution,
which learn from rewards alone. And, given another ``teacher``, the second
half of a trainer from rewards alone: a
:class:`~amaze.evaluation.controllers.GuidedController` steers a continuous
robot where a hybrid agent (evolved or trained by RL on rewards) goes, and the
network learns that agent's decisions with continuous control, knowing no
maze's solution (``track=True`` keeps that agent on its own track and brings
a straying robot back to it, so that the labels on a student's mistakes lead
back to the agent's way rather than turn a memoryless agent round).
``benchmarks/bench_oracle_imitation.py`` runs it
(``--guide AGENT``) and scores the network on the suites. The teacher of a continuous
robot steers without braking by default (``damping = 0``: the image shows no
velocity, and this law solves the suite, see :class:`OracleController`).

torch is imported when a network is built, not with this module.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from amaze.agents.engine import BatchEngine
from amaze.evaluation.controllers import OracleController
from amaze.evaluation.policy import as_policy_observations
from amaze.maze import Maze, MazeSpec
from amaze.validation import check_integer, check_number

from .config import EvolutionConfigError
from .convolution import FILTER_SIDE
from .networks import NetworkSpec
from .population import PopulationEvaluator

__all__ = [
    "KEEP",
    "ImitationConfig",
    "ImitationResult",
    "imitate",
    "network_inputs",
    "torch_network",
]

#: The continuous teacher's gain and damping (see the module docstring).
TEACHER_GAIN = 2.0
TEACHER_DAMPING = 0.0
#: Which network :func:`imitate` hands over: the last iteration's, the best on validation,
#: or the mean of the late iterations' parameters.
KEEP = ("last", "best", "average")
#: Bounds of the config's counts: ``max_samples`` keeps the samples held in memory
#: under about 9 GB for a 15 x 15 image read pixel by pixel (225 float32 inputs; a
#: convolutional network keeps the uint8 images, a quarter of that).
_MAXIMA = {
    "iterations": 1000, "agents": 1 << 16, "steps": 100_000, "updates": 1_000_000,
    "batch": 1 << 20, "max_samples": 10_000_000,
}  # fmt: skip


@dataclass(frozen=True)
class ImitationConfig:
    """How long and how DAgger teaches (see the module docstring).

    ``agents`` robots are driven at once for ``steps`` batch steps per
    iteration (their episodes go on across iterations); the network then takes
    ``updates`` Adam steps of ``batch`` samples at ``learning_rate``, times
    ``learning_rate_decay`` per iteration (1: the same rate throughout).
    ``keep``: the network handed over, the ``"last"`` iteration's, the
    ``"best"`` on the validation mazes (which :func:`imitate` then needs), or
    the ``"average"`` of the parameters of iterations ``average_from`` to the
    last (``None``: ``iterations // 2``; given only with ``"average"``).
    """

    iterations: int = 10
    agents: int = 512
    steps: int = 400
    updates: int = 1500
    batch: int = 4096
    learning_rate: float = 3e-3
    learning_rate_decay: float = 1.0
    max_samples: int = 3_000_000
    seed: int = 0
    keep: str = "last"
    average_from: int | None = None

    def __post_init__(self) -> None:
        for name in ("iterations", "agents", "steps", "updates", "batch", "max_samples"):
            check_integer(
                name, getattr(self, name), minimum=1, maximum=_MAXIMA[name],
                error=EvolutionConfigError,
            )  # fmt: skip
        check_integer("seed", self.seed, minimum=0, error=EvolutionConfigError)
        check_number(
            "learning_rate", self.learning_rate, minimum=0.0, strict_minimum=True,
            error=EvolutionConfigError,
        )  # fmt: skip
        check_number(
            "learning_rate_decay", self.learning_rate_decay, minimum=0.0, maximum=1.0,
            strict_minimum=True, error=EvolutionConfigError,
        )  # fmt: skip
        if self.keep not in KEEP:
            raise EvolutionConfigError(f"keep {self.keep!r} is not one of {', '.join(KEEP)}")
        if self.average_from is not None:
            if self.keep != "average":
                raise EvolutionConfigError(
                    f'average_from {self.average_from!r} chooses what keep "average" averages;'
                    f" keep is {self.keep!r}"
                )
            check_integer(
                "average_from", self.average_from, minimum=0, maximum=self.iterations - 1,
                error=EvolutionConfigError,
            )  # fmt: skip

    @property
    def first_averaged(self) -> int:
        """The first iteration whose parameters ``keep = "average"`` averages."""
        return self.iterations // 2 if self.average_from is None else self.average_from


@dataclass
class ImitationResult:
    """The network handed over (``(spec.n_params,)``, float64), one record per iteration,
    and the iteration whose network it is (``config.keep``; with ``"average"`` the last,
    ``averaged_from`` the first averaged, -1 otherwise)."""

    params: np.ndarray
    history: list[dict[str, float]] = field(default_factory=list)
    kept_iteration: int = -1
    averaged_from: int = -1


def network_inputs(spec: NetworkSpec, observations: np.ndarray) -> np.ndarray:
    """What :func:`torch_network` reads: :meth:`NetworkSpec.encode`'s inputs, or the images.

    A convolutional network's inputs depend on its filters, so it reads the
    uint8 ``(n, v, v)`` images themselves (a quarter of float32's memory).
    """
    if not spec.filters:
        return spec.encode(observations)
    v = int(spec.robot_info.vision)
    return np.ascontiguousarray(np.asarray(observations, dtype=np.uint8).reshape(-1, v, v))


def torch_network(spec: NetworkSpec) -> Any:
    """A torch module computing what ``spec``'s networks compute, in float32.

    Called on a tensor of :func:`network_inputs`, it returns the
    accelerations (continuous robots) or the four direction scores (discrete
    outputs); ``flat_params()`` and ``load_params(vector)`` convert from and to
    the spec's parameter layout. A convolutional network
    (:mod:`evolution.convolution`) slides its 3x3 filters over the image / 255
    with the spec's stride; with rotations, in their four turns, and direction
    ``d`` reads the maps of the image turned ``d`` times
    (:func:`~evolution.convolution.feature_turns`).
    """
    import torch

    activations: dict[str, Callable[[Any], Any]] = {
        "tanh": torch.tanh, "relu": torch.relu, "sigmoid": torch.sigmoid,
        "identity": lambda x: x,
    }  # fmt: skip

    class _Network(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.continuous = not spec.robot_info.discrete_outputs
            self.turned = spec.copies > 1
            if self.turned:
                self.register_buffer(
                    "index", torch.as_tensor(spec.rotation_index(), dtype=torch.long)
                )
            self.conv = None
            if spec.filters:
                self.conv = torch.nn.Conv2d(1, spec.filters, FILTER_SIDE, stride=spec.stride)
            self.layers = torch.nn.ModuleList(
                torch.nn.Linear(d_in, d_out) for d_in, d_out in spec.layer_shapes
            )
            self.activation = activations[spec.activation]

        def features(self, inputs: Any) -> Any:
            """The dense layers' inputs: ``(n, n_inputs)``, or ``(n, 4, n_inputs)`` turned."""
            if self.conv is None:
                return inputs[:, self.index] if self.turned else inputs
            images = inputs.to(torch.float32)[:, None] / 255.0
            weight, bias = self.conv.weight, self.conv.bias
            if self.turned:  # filter d F + f: filter f turned d quarter-turns anticlockwise
                weight = torch.cat([torch.rot90(weight, d, dims=(2, 3)) for d in range(4)])
                bias = bias.repeat(4)
            maps = torch.nn.functional.conv2d(images, weight, bias, stride=spec.stride)
            x = self.activation(maps).flatten(1)
            return x[:, self.index] if self.turned else x

        def forward(self, inputs: Any) -> Any:
            x = self.features(inputs)
            for k, layer in enumerate(self.layers):
                x = layer(x)
                if k < len(self.layers) - 1:
                    x = self.activation(x)
            if self.turned:
                scores = x[..., 0]  # (n, 4): E, N, W, S
                if not self.continuous:
                    return scores
                return torch.tanh(
                    torch.stack([scores[:, 0] - scores[:, 2], scores[:, 1] - scores[:, 3]], 1)
                )
            return torch.tanh(x) if self.continuous else x

        def flat_params(self) -> np.ndarray:
            parts = []
            if self.conv is not None:
                parts.append(self.conv.weight.detach().numpy().ravel())
                parts.append(self.conv.bias.detach().numpy())
            for layer in self.layers:
                parts.append(layer.weight.detach().numpy().T.ravel())
                parts.append(layer.bias.detach().numpy())
            return np.concatenate(parts).astype(np.float64)

        def load_params(self, params: np.ndarray) -> None:
            with torch.no_grad():
                if self.conv is not None:
                    weights, biases = spec.filter_params(params)
                    self.conv.weight.copy_(torch.as_tensor(weights[:, None], dtype=torch.float32))
                    self.conv.bias.copy_(torch.as_tensor(biases, dtype=torch.float32))
                for layer, (weights, biases) in zip(
                    self.layers, spec.unflatten(params), strict=True
                ):
                    layer.weight.copy_(torch.as_tensor(weights.T, dtype=torch.float32))
                    layer.bias.copy_(torch.as_tensor(biases, dtype=torch.float32))

    return _Network()


def imitate(
    spec: NetworkSpec,
    mazes: Sequence[Maze | MazeSpec | str],
    config: ImitationConfig | None = None,
    *,
    validation: Sequence[Maze | MazeSpec | str] = (),
    teacher: Any = None,
    on_iteration: Callable[[dict[str, float], np.ndarray], None] | None = None,
) -> ImitationResult:
    """Teach ``spec``'s network the oracle's (or ``teacher``'s) actions on ``mazes`` by DAgger.

    ``teacher``: whose actions instead of the oracle's, a controller of the
    spec's robot bound to the engine (``bind(engine)``) and called on its
    observations, e.g. a :class:`~amaze.evaluation.controllers.GuidedController`
    that steers a continuous robot where a hybrid agent trained from rewards
    would go (no privileged knowledge of the maze).

    ``on_iteration(record, params)`` hears of each iteration (``iteration``,
    ``beta``, ``samples``, ``loss``: the last batch's, ``learning_rate``, and
    with ``validation`` mazes ``validation_success`` and
    ``validation_progress``; with ``keep = "average"``, from the first
    averaged iteration on, ``average_validation_success`` and
    ``average_validation_progress``: the running mean's) with that iteration's
    parameters. The same spec,
    mazes and config give the same parameters on one machine (torch's CPU
    kernels may round differently elsewhere).
    """
    import torch

    config = config or ImitationConfig()
    if config.keep == "best" and not validation:
        raise EvolutionConfigError('keep "best" needs validation mazes to choose on')
    if teacher is not None and not (callable(teacher) and callable(getattr(teacher, "bind", None))):
        raise EvolutionConfigError(
            "the teacher must be a controller with a bind(engine) hook,"
            f" got {type(teacher).__name__}"
        )
    judge = None
    if validation:
        judge = PopulationEvaluator(list(validation), spec.robot, fitness="path_progress")
    best_key = (-1.0, -1.0)
    total = np.zeros(spec.n_params)  # keep "average": the sum of the averaged parameters
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    engine = BatchEngine(list(mazes), spec.robot, config.agents)
    robot = spec.robot_info
    if teacher is None and robot.discrete_outputs:
        teacher = OracleController(robot)
    elif teacher is None:
        teacher = OracleController(robot, gain=TEACHER_GAIN, damping=TEACHER_DAMPING)
    teacher.bind(engine)
    network = torch_network(spec)
    optimiser = torch.optim.Adam(network.parameters(), lr=config.learning_rate)
    label_shape = (2,) if not robot.discrete_outputs else ()
    label_type = np.float32 if not robot.discrete_outputs else np.int64
    if spec.filters:
        v = int(robot.vision)
        inputs = np.empty((0, v, v), dtype=np.uint8)
    else:
        inputs = np.empty((0, spec.n_inputs), dtype=np.float32)
    labels = np.empty((0, *label_shape), dtype=label_type)
    observations = engine.reset()
    result = ImitationResult(params=network.flat_params())
    for iteration in range(config.iterations):
        beta = 0.5**iteration
        new_inputs, new_labels = [], []
        for _ in range(config.steps):
            encoded = network_inputs(spec, observations)
            taught_actions = np.asarray(teacher(as_policy_observations(observations, robot)))
            with torch.no_grad():
                output = network(torch.as_tensor(encoded)).numpy()
            student = output.argmax(axis=1) if robot.discrete_outputs else output
            taught = rng.random(engine.n_agents) < beta
            mask = taught if robot.discrete_outputs else taught[:, None]
            actions = np.where(mask, taught_actions, student)
            new_inputs.append(encoded)
            new_labels.append(taught_actions.astype(label_type))
            observations = engine.step(actions).observations
        inputs = np.concatenate([inputs, *new_inputs])[-config.max_samples :]
        labels = np.concatenate([labels, *new_labels])[-config.max_samples :]
        x, y = torch.as_tensor(inputs), torch.as_tensor(labels)
        learning_rate = config.learning_rate * config.learning_rate_decay**iteration
        for group in optimiser.param_groups:
            group["lr"] = learning_rate
        for _ in range(config.updates):
            batch = torch.as_tensor(rng.integers(0, len(x), config.batch))
            output = network(x[batch])
            if robot.discrete_outputs:
                loss = torch.nn.functional.cross_entropy(output, y[batch])
            else:
                loss = torch.mean((output - y[batch]) ** 2)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
        params = network.flat_params()
        record = {
            "iteration": float(iteration), "beta": beta, "samples": float(len(x)),
            "loss": float(loss.item()), "learning_rate": learning_rate,
        }  # fmt: skip
        key = best_key
        if judge is not None:
            key = _validate(spec, judge, params)
            record.update(validation_success=key[0], validation_progress=key[1])
        if config.keep == "last" or (config.keep == "best" and key > best_key):
            best_key, result.params, result.kept_iteration = key, params, iteration
        elif config.keep == "average" and iteration >= config.first_averaged:
            total += params
            mean = total / (iteration - config.first_averaged + 1)
            result.params, result.kept_iteration = mean, iteration
            result.averaged_from = config.first_averaged
            if judge is not None:
                success, progress = _validate(spec, judge, mean)
                record.update(
                    average_validation_success=success, average_validation_progress=progress
                )
        result.history.append(record)
        if on_iteration is not None:
            on_iteration(record, params)
    return result


def _validate(
    spec: NetworkSpec, judge: PopulationEvaluator, params: np.ndarray
) -> tuple[float, float]:
    """Success rate and path progress of the network ``params`` on ``judge``'s mazes."""
    scores = judge.evaluate(spec.population(params[None, :]))
    return float(scores.success_rate[0]), float(scores.fitness[0])

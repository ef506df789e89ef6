"""The NEAT-like algorithm's parameters: :class:`NeatConfig` and the rules its values obey.

One dataclass holds every rate, size and threshold of the GA (mutation and
crossover rates, speciation, stagnation, elitism, selection), read from and
written to JSON with the run's configuration. It lives apart from the
algorithm so that a run folder's options can be checked, and an agent file's
settings read, without building a population.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

from amaze.runs.config import config_from_dict
from amaze.validation import check_integer, check_number
from evolution import EvolutionConfigError
from evolution.neat.compile import ACTIVATIONS
from evolution.networks import SYMMETRIES

__all__ = ["NeatConfig"]


#: The bounds of each numeric field, as keyword arguments of
#: :func:`~amaze.validation.check_integer` (int fields) or
#: :func:`~amaze.validation.check_number` (float fields); fields not listed
#: only need to be finite numbers.
_PROBABILITY: dict[str, Any] = {"minimum": 0, "maximum": 1}
_FRACTION: dict[str, Any] = {"minimum": 0, "maximum": 1, "strict_minimum": True}
_NON_NEGATIVE: dict[str, Any] = {"minimum": 0}
_POSITIVE: dict[str, Any] = {"minimum": 0, "strict_minimum": True}
_RULES: dict[str, dict[str, Any]] = {
    "population_size": {"minimum": 2},
    "stagnation": {"minimum": 1},
    "min_species_size": {"minimum": 1},
    "tournament_size": {"minimum": 1},
    "elitism": _NON_NEGATIVE,
    "target_species": _NON_NEGATIVE,  # 0: a fixed threshold
    "compatibility_threshold": _POSITIVE,
    "threshold_step": _POSITIVE,
    "weight_max": _POSITIVE,
    **dict.fromkeys(
        ("initial_connection_fraction", "image_connection_fraction", "survival_fraction"),
        _FRACTION,
    ),
    **dict.fromkeys(
        (
            "weight_init_stdev",
            "weight_mutate_power",
            "bias_init_stdev",
            "bias_mutate_power",
            "compatibility_excess",
            "compatibility_disjoint",
            "compatibility_weight",
        ),
        _NON_NEGATIVE,
    ),
    **dict.fromkeys(
        (
            "weight_mutate_rate",
            "weight_replace_rate",
            "bias_mutate_rate",
            "bias_replace_rate",
            "add_connection_rate",
            "add_node_rate",
            "toggle_enable_rate",
            "activation_mutate_rate",
            "crossover_rate",
            "disable_inherit_rate",
        ),
        _PROBABILITY,
    ),
}


@dataclass
class NeatConfig:
    """Parameters of the NEAT-like algorithm (defaults after Stanley & Miikkulainen, 2002).

    Probabilities are per offspring unless said otherwise. ``activation`` is
    the hidden nodes' activation (outputs are linear for discrete actions,
    tanh for accelerations). ``target_species`` > 0 adapts the compatibility
    threshold each generation towards that many species, multiplying or dividing
    it by ``1 + threshold_step``. The threshold (1.0, lower than the paper's 3.0)
    suits the normalised distance of genomes of 20 connection genes or more,
    where weight differences dominate. ``symmetry`` ``"rotations"`` evolves
    genomes of one output that score each direction on the cell turned that
    way (:class:`~evolution.neat.compile.GenomePopulation`; a continuous
    robot accelerates along the scores' differences), as CMA-ES's networks may
    (:mod:`evolution.networks`, "Symmetry").
    """

    population_size: int = 100
    activation: str = "tanh"
    initial_connection_fraction: float = 1.0
    image_connection_fraction: float = 0.05
    weight_init_stdev: float = 1.0
    weight_max: float = 8.0
    weight_mutate_rate: float = 0.8
    weight_replace_rate: float = 0.1
    weight_mutate_power: float = 0.5
    bias_init_stdev: float = 1.0
    bias_mutate_rate: float = 0.7
    bias_replace_rate: float = 0.1
    bias_mutate_power: float = 0.5
    add_connection_rate: float = 0.1
    add_node_rate: float = 0.05
    toggle_enable_rate: float = 0.01
    activation_mutate_rate: float = 0.0
    crossover_rate: float = 0.75
    disable_inherit_rate: float = 0.75
    compatibility_excess: float = 1.0
    compatibility_disjoint: float = 1.0
    compatibility_weight: float = 0.4
    compatibility_threshold: float = 1.0
    target_species: int = 8
    threshold_step: float = 0.1
    stagnation: int = 15
    elitism: int = 1
    survival_fraction: float = 0.2
    min_species_size: int = 2
    tournament_size: int = 2
    symmetry: str = "none"

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check and normalise every value; raise :class:`EvolutionConfigError` naming a bad one."""
        for field in fields(self):
            name, value = field.name, getattr(self, field.name)
            bounds = _RULES.get(name, {})
            if field.type == "int":
                value = check_integer(
                    f"NEAT config '{name}'", value, **bounds, error=EvolutionConfigError
                )
            elif field.type == "float":
                value = check_number(
                    f"NEAT config '{name}'", value, **bounds, error=EvolutionConfigError
                )
            setattr(self, name, value)
        if self.symmetry not in SYMMETRIES:
            raise EvolutionConfigError(
                f"NEAT config 'symmetry' must be one of {', '.join(SYMMETRIES)},"
                f" got {self.symmetry!r}"
            )
        if self.activation not in ACTIVATIONS:
            raise EvolutionConfigError(
                f"NEAT config 'activation' must be one of {', '.join(ACTIVATIONS)}, "
                f"got {self.activation!r}"
            )

    def to_dict(self) -> dict[str, Any]:
        """The configuration as a JSON-ready dictionary."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> NeatConfig:
        """A configuration from a mapping; missing keys take their defaults.

        Unknown keys and bad values raise :class:`EvolutionConfigError` naming them.
        """
        return config_from_dict(cls, data, EvolutionConfigError, "NEAT config")

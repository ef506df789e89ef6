"""The search-algorithm protocol and the registry that builds algorithms by name."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from evolution import EvolutionConfigError
from evolution.algorithms import ALGORITHMS, SearchAlgorithm, algorithm_class, make_algorithm
from evolution.cmaes import CMAESAlgorithm, CMAESConfig
from evolution.neat import NeatAlgorithm, NeatConfig
from tests.evolution.neat.conftest import fingerprint

ROOT = Path(__file__).resolve().parents[2]


def test_the_registry_names_both_algorithms() -> None:
    assert list(ALGORITHMS) == ["cmaes", "neat"]
    assert algorithm_class("cmaes") is CMAESAlgorithm
    assert algorithm_class("neat") is NeatAlgorithm
    assert CMAESAlgorithm.config_class is CMAESConfig
    assert NeatAlgorithm.config_class is NeatConfig


@pytest.mark.parametrize("name", sorted(ALGORITHMS))
@pytest.mark.parametrize("robot", ["DD", "H7"])
def test_registered_algorithms_satisfy_the_protocol(name: str, robot: str) -> None:
    algorithm = make_algorithm(name, {"population_size": 6}, robot, 0)
    assert isinstance(algorithm, SearchAlgorithm)
    assert isinstance(algorithm, algorithm_class(name))
    assert algorithm.generation == 0 and algorithm.champion is None
    assert algorithm.stopped is False and algorithm.stats() == {}
    candidates = algorithm.ask()
    assert len(candidates) == 6
    policy = algorithm.population_policy(candidates)
    assert policy.n_policies == 6
    algorithm.tell(candidates, np.arange(6.0))
    assert algorithm.generation == 1 and algorithm.champion[1] == 5.0
    assert algorithm.stats()["best"] == 5.0
    arrays, architecture = algorithm.champion_arrays()
    assert architecture["type"] in ("mlp", "neat") and arrays


def test_an_object_lacking_part_of_the_interface_is_no_search_algorithm() -> None:
    class AskOnly:
        def ask(self) -> list:
            return []

    assert not isinstance(AskOnly(), SearchAlgorithm)


@pytest.mark.parametrize("name", ["pso", "CMAES", "", None, ["neat"]])
def test_unknown_names_are_refused_naming_them(name: object) -> None:
    with pytest.raises(EvolutionConfigError, match="cmaes, neat") as caught:
        algorithm_class(name)
    assert repr(name) in str(caught.value)
    with pytest.raises(EvolutionConfigError, match="unknown algorithm"):
        make_algorithm(name, {}, "DD", 0)


@pytest.mark.parametrize(
    ("name", "options", "named"),
    [
        ("cmaes", {"sigma": 2.0}, "sigma"),
        ("cmaes", {"restarts": -1}, "restarts"),
        ("neat", {"speciess": 3}, "speciess"),
        ("neat", {"crossover_rate": 1.5}, "crossover_rate"),
    ],
)
def test_options_are_read_by_the_algorithm_config(name: str, options: dict, named: str) -> None:
    with pytest.raises(EvolutionConfigError, match=named):
        make_algorithm(name, options, "DD", 0)


def test_make_algorithm_asks_what_the_class_asks_with_the_same_seed() -> None:
    options = {"population_size": 8, "network": {"hidden": [3]}}
    built = make_algorithm("cmaes", options, "DD", 7).ask()
    direct = CMAESAlgorithm(CMAESConfig.from_dict(options), "DD", 7).ask()
    assert len(built) == len(direct) == 8
    for a, b in zip(built, direct, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(built[0], make_algorithm("cmaes", options, "DD", 8).ask()[0])
    options = {"population_size": 12, "image_connection_fraction": 0.1}
    built = make_algorithm("neat", options, "H5", 7).ask()
    direct = NeatAlgorithm(NeatConfig(**options), "H5", 7).ask()
    assert fingerprint(built) == fingerprint(direct)
    assert fingerprint(built) != fingerprint(make_algorithm("neat", options, "H5", 8).ask())


def test_no_algorithm_module_is_imported_before_it_is_asked_for() -> None:
    code = (
        "import sys, evolution.algorithms as a\n"
        "heavy = ('evolution.cmaes', 'evolution.neat', 'cma', 'deap')\n"
        "assert not [m for m in heavy if m in sys.modules], sorted(sys.modules)\n"
        "a.algorithm_class('neat')\n"
        "assert 'evolution.neat' in sys.modules and 'evolution.cmaes' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)

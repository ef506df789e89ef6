"""The NEAT-like genetic algorithm (NeuroEvolution of Augmenting Topologies) on ``deap``.

:class:`NeatAlgorithm` evolves genomes (:mod:`evolution.neat.genome`) from
minimal networks, complexifying them with the operators of
:mod:`evolution.neat.operators`, speciating the population and sharing
fitness within species (:mod:`evolution.neat.species`). It is driven by ask /
tell, like :class:`~evolution.cmaes.CMAESAlgorithm`, and never calls the
simulator: it is a :class:`~evolution.algorithms.SearchAlgorithm`.

``deap`` provides the toolbox (``mate``, ``mutate``, ``select`` with
``tools.selTournament`` within species), the statistics and logbook, and the
hall of fame holding the champion. deap draws from Python's global ``random``;
the algorithm swaps its own saved state in and out around each of its steps,
so that a run is deterministic given its seed and a pickled algorithm resumes
bit-identically, whatever else uses ``random`` meanwhile.
"""

from __future__ import annotations

import contextlib
import math
import random
from collections.abc import Iterator, Sequence
from typing import Any, ClassVar

import numpy as np
from deap import base, tools

from amaze.agents.robot import Robot, as_robot
from evolution import EvolutionConfigError
from evolution.neat.compile import GenomePopulation, genome_to_arrays, robot_io
from evolution.neat.config import NeatConfig
from evolution.neat.genome import Genome, InnovationTracker, new_genome
from evolution.neat.operators import crossover, mutate
from evolution.neat.species import (
    Species,
    allot_offspring,
    remove_stagnant,
    shared_fitness,
    speciate,
    update_progress,
)

__all__ = ["NeatAlgorithm"]


def _fitness_value(genome: Genome) -> float:
    return genome.fitness.values[0]


class NeatAlgorithm:
    """NEAT-like evolution of genomes for ``robot``, driven by ask / tell.

    ``ask()`` gives the population to evaluate, :meth:`population_policy`
    compiles it into one policy for the batch engine, ``tell(genomes, fitness)``
    records the fitness, updates the champion (deap hall of fame) and the
    statistics (deap logbook) and breeds the next generation. Deterministic
    given ``seed``; pickling the object is a checkpoint that resumes
    bit-identically. It satisfies :class:`~evolution.algorithms.SearchAlgorithm`.
    """

    #: The configuration dataclass (:func:`evolution.algorithms.make_algorithm` reads it).
    config_class: ClassVar[type[NeatConfig]] = NeatConfig

    def __init__(self, config: NeatConfig, robot: Robot | str, seed: int) -> None:
        if isinstance(config, dict):
            config = NeatConfig.from_dict(config)
        if not isinstance(config, NeatConfig):
            raise EvolutionConfigError(f"expected a NeatConfig, got {type(config).__name__}")
        config.validate()
        self.config = config
        self.robot = as_robot(robot)
        self.seed = int(seed)
        n_inputs, n_outputs = robot_io(self.robot, config.symmetry)  # CC refuses rotations
        self.tracker = InnovationTracker(n_inputs, n_outputs)
        self.species: list[Species] = []
        self.threshold = config.compatibility_threshold
        self.logbook = tools.Logbook()
        self.hall_of_fame = tools.HallOfFame(1)
        self._generation = 0
        self._next_species = 0
        self._random_state = random.Random(self.seed).getstate()
        self._build_toolbox()
        with self._own_random():
            self.population = [
                new_genome(self.robot, self.tracker, config) for _ in range(config.population_size)
            ]

    # -- state -------------------------------------------------------------

    def _build_toolbox(self) -> None:
        toolbox = base.Toolbox()
        toolbox.register("clone", Genome.copy)
        toolbox.register("mate", crossover, config=self.config)
        toolbox.register("mutate", mutate, config=self.config, tracker=self.tracker)
        toolbox.register("select", tools.selTournament, tournsize=self.config.tournament_size)
        self.toolbox = toolbox

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["toolbox"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._build_toolbox()

    @contextlib.contextmanager
    def _own_random(self) -> Iterator[None]:
        """Run with the algorithm's state in ``random``, leaving the caller's intact."""
        outer = random.getstate()
        random.setstate(self._random_state)
        try:
            yield
        finally:
            self._random_state = random.getstate()
            random.setstate(outer)

    # -- interface ---------------------------------------------------------

    @property
    def generation(self) -> int:
        """Generations told so far."""
        return self._generation

    @property
    def stopped(self) -> bool:
        """Always False: NEAT has no termination criterion of its own.

        Stagnant species are removed but the best one always survives, so the
        population never dies out; the run's budget decides when to stop.
        """
        return False

    @property
    def champion(self) -> tuple[Genome, float] | None:
        """The best genome ever evaluated and its fitness, None before the first tell."""
        if len(self.hall_of_fame) == 0:
            return None
        best = self.hall_of_fame[0]
        return best, float(best.fitness.values[0])

    def champion_arrays(self) -> tuple[dict[str, np.ndarray], dict]:
        """The champion compiled by :func:`genome_to_arrays` (for agent files)."""
        champion = self.champion
        if champion is None:
            raise RuntimeError("no champion yet: tell() the fitness of a generation first")
        return genome_to_arrays(champion[0])

    def candidate_arrays(self, genome: Genome) -> tuple[dict[str, np.ndarray], dict]:
        """A genome compiled for an agent file (as :meth:`champion_arrays`)."""
        return genome_to_arrays(genome)

    def ask(self) -> list[Genome]:
        """The genomes to evaluate this generation."""
        return list(self.population)

    def population_policy(self, genomes: Sequence[Genome]) -> GenomePopulation:
        """``genomes`` compiled into one population policy (agent ``k`` uses genome ``k // M``)."""
        return GenomePopulation.from_genomes(genomes, self.robot, symmetry=self.config.symmetry)

    def tell(self, genomes: Sequence[Genome], fitness: np.ndarray) -> None:
        """Record the fitness of the asked genomes and breed the next generation."""
        fitness = np.asarray(fitness, dtype=np.float64).reshape(-1)
        if len(genomes) != len(self.population) or any(
            a is not b for a, b in zip(genomes, self.population, strict=False)
        ):
            raise ValueError("tell() needs the genomes of the last ask(), in the same order")
        if fitness.shape[0] != len(genomes):
            raise ValueError(f"{fitness.shape[0]} fitness values for {len(genomes)} genomes")
        if not np.all(np.isfinite(fitness)):
            raise ValueError("fitness values must be finite")
        for genome, value in zip(genomes, fitness.tolist(), strict=True):
            genome.fitness.values = (value,)
        self.hall_of_fame.update(self.population)
        with self._own_random():
            self._next_generation()

    def stats(self) -> dict[str, float]:
        """The last generation's statistics (best, mean, std, min, n_species...), {} before."""
        if not self.logbook:
            return {}
        return {key: float(value) for key, value in self.logbook[-1].items()}

    def reseed(self, seed: int) -> None:
        """A fresh state of ``random`` seeded with ``seed`` (the only stream NEAT draws from)."""
        self.seed = int(seed)
        self._random_state = random.Random(self.seed).getstate()

    def forget_champion(self) -> None:
        """Empty the hall of fame and restart the species' progress records.

        Each species' best fitness was measured on the old mazes: kept, it
        would make every species look stagnant on harder new mazes (and have
        them removed), so stagnation is counted afresh from the next ``tell``.
        """
        self.hall_of_fame.clear()
        for s in self.species:
            s.best_fitness = -math.inf
            s.last_improved = self._generation

    # -- one generation ----------------------------------------------------

    def _next_generation(self) -> None:
        config = self.config
        generation = self._generation
        self.species, self._next_species = speciate(
            self.population, self.species, self.threshold, config, generation, self._next_species
        )
        update_progress(self.species, generation)
        n_species = len(self.species)
        self._record(n_species)
        if config.target_species:
            if n_species < config.target_species:
                self.threshold /= 1.0 + config.threshold_step
            elif n_species > config.target_species:
                self.threshold *= 1.0 + config.threshold_step
        self.species = remove_stagnant(self.species, generation, config.stagnation)
        counts = allot_offspring(
            shared_fitness(self.species), config.population_size, config.min_species_size
        )
        offspring: list[Genome] = []
        for s, count in zip(self.species, counts, strict=True):
            offspring.extend(self._reproduce(s, count))
        self.species = [s for s, count in zip(self.species, counts, strict=True) if count]
        for s in self.species:
            s.members = []  # rebuilt by the next speciation; keeps checkpoints small
        self.population = offspring
        self._generation += 1

    def _reproduce(self, species: Species, count: int) -> list[Genome]:
        """``count`` offspring of a species: its elites, then children of its survivors."""
        config, toolbox = self.config, self.toolbox
        ranked = sorted(species.members, key=_fitness_value, reverse=True)
        children: list[Genome] = []
        for elite in ranked[: min(config.elitism, count)]:
            child = toolbox.clone(elite)
            del child.fitness.values
            children.append(child)
        survivors = ranked[: max(1, math.ceil(config.survival_fraction * len(ranked)))]
        while len(children) < count:
            if len(survivors) > 1 and random.random() < config.crossover_rate:
                first, second = toolbox.select(survivors, 2)
                child = toolbox.mate(first, second)
            else:
                child = toolbox.clone(toolbox.select(survivors, 1)[0])
            (child,) = toolbox.mutate(child)
            children.append(child)
        return children

    def _record(self, n_species: int) -> None:
        statistics = tools.Statistics(_fitness_value)
        statistics.register("best", np.max)
        statistics.register("mean", np.mean)
        statistics.register("std", np.std)
        statistics.register("min", np.min)
        record = statistics.compile(self.population)
        self.logbook.record(
            gen=self._generation,
            evals=len(self.population),
            **record,
            champion=self.hall_of_fame[0].fitness.values[0],
            n_species=n_species,
            threshold=self.threshold,
            hidden=float(np.mean([g.n_hidden for g in self.population])),
            connections=float(np.mean([g.n_enabled for g in self.population])),
        )

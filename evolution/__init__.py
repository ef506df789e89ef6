"""Neuroevolution on the AMaze batch engine: CMA-ES and a NEAT-like GA.

``evolution`` depends on :mod:`amaze` (never the reverse, never on
``rl_baselines``) and on ``cma`` and ``deap``.

* :mod:`evolution.networks`: fixed-topology networks (linear, MLP, a small
  image encoder for hybrid and continuous robots) as flat parameter vectors,
  a whole population evaluated in one batched forward pass;
* :mod:`evolution.neat`: the NEAT-like GA, a package split by concept: its
  config, the genome (node and connection genes with innovation numbers), its
  operators on ``deap``, species, the algorithm, and the compilation of
  genomes to a batched feed-forward evaluator;
* :mod:`evolution.population`: population policies played on the batch
  engine (P policies x M episodes stepped together) and their fitness;
* :mod:`evolution.agent_file`: evolved agents saved as ``.npz`` + JSON, never pickled;
* :mod:`evolution.algorithms`: the ask / tell interface every search
  algorithm offers the run loop (:class:`~evolution.algorithms.SearchAlgorithm`)
  and the registry that builds one by name;
* :mod:`evolution.cmaes`, :mod:`evolution.config`, :mod:`evolution.run`,
  :mod:`evolution.cli`: the algorithms, the run config, run folders with
  checkpoint/resume, and the ``amaze-evolve`` command;
* :mod:`evolution.learner`, :mod:`evolution.curriculum`: evolution as a
  curriculum learner, and the curriculum regimes (``--regime edhucat``,
  ``--regime interpolation``) of ``amaze-evolve``;
* :mod:`evolution.imitation`: the oracle's actions taught to a network by
  DAgger, a capacity check and a trainer with a privileged teacher (torch,
  imported only there and only when used).
"""

from __future__ import annotations

from amaze.errors import AmazeError

__all__ = ["EvolutionConfigError"]


class EvolutionConfigError(AmazeError):
    """Bad user input to the evolution package (algorithm, network, budget, config key...)."""

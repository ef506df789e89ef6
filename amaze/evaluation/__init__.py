"""How agents are scored: the policy protocol, controllers, input recognition, the suite.

* :mod:`~amaze.evaluation.policy`: a policy maps a batch of observations to a batch
  of actions; :func:`run_episodes`, :func:`record_episode`;
* :mod:`~amaze.evaluation.controllers`: random, oracle and tabular controllers;
* :mod:`~amaze.evaluation.inputs`: the input-recognition test (its picture in
  :mod:`~amaze.evaluation.inputs_picture`);
* :mod:`~amaze.evaluation.suite`: the standard evaluation suite (each maze in its
  rotations, :func:`amaze.maze.rotations`) and the paper's (:func:`paper_suite`, built
  by :mod:`~amaze.evaluation.paper_suite`);
* :mod:`~amaze.evaluation.protocol`: :func:`evaluate` / :class:`Evaluator`, the one
  protocol every agent goes through.
"""

from amaze.evaluation.policy import EpisodeResults, Policy, record_episode, run_episodes
from amaze.evaluation.protocol import EpisodeResult, EvaluationReport, Evaluator, evaluate
from amaze.evaluation.suite import (
    PAPER_EVALUATION_MAZE,
    PAPER_TRAINING_MAZE,
    EvaluationSuite,
    PaperSuite,
    paper_suite,
    standard_suite,
)

__all__ = [
    "PAPER_EVALUATION_MAZE",
    "PAPER_TRAINING_MAZE",
    "EpisodeResult",
    "EpisodeResults",
    "EvaluationReport",
    "EvaluationSuite",
    "Evaluator",
    "PaperSuite",
    "Policy",
    "evaluate",
    "paper_suite",
    "record_episode",
    "run_episodes",
    "standard_suite",
]

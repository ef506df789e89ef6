"""Run infrastructure shared by the training commands (``amaze-train``, ``amaze-evolve``).

* :mod:`~amaze.runs.lifecycle`: the one run lifecycle (fresh start, resume after
  a kill, final report on the standard suite); a trainer supplies its loop;
* :mod:`~amaze.runs.config`: run configs whose documented fields drive
  ``config.json``, the command line and ``--help``;
* :mod:`~amaze.runs.folder`: atomic writers and ``progress.csv``;
* :mod:`~amaze.runs.replicates`: ``--replicates K`` as parallel worker processes;
* :mod:`~amaze.runs.launchers`: where those processes run (this machine, or
  Ray tasks: :mod:`~amaze.runs.ray_tasks`) and their one loop;
* :mod:`~amaze.runs.cluster`: Ray as an optional extra, and connecting to it;
* :mod:`~amaze.runs.command`: the command-line skeleton with the one error contract.
"""

"""``python -m amaze`` runs the ``amaze`` command."""

from amaze.cli.main import entry_point

entry_point()

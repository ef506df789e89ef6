"""Pieces shared by the training commands (``amaze-train``, ``amaze-evolve``).

* :class:`CommandParser`: argparse with the project's error contract, one line
  ``error: ...`` on stderr and exit status 2;
* :func:`read_json_object`: a ``--config`` file, with errors naming the file.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, NoReturn

__all__ = ["CommandParser", "read_json_object"]


class CommandParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exits with status 2."""

    def error(self, message: str) -> NoReturn:
        print(f"error: {message}", file=sys.stderr)
        raise SystemExit(2)


def read_json_object(path: str, error: type[ValueError]) -> dict[str, Any]:
    """The JSON object in the file ``path``; raise ``error`` naming the file otherwise."""
    try:
        loaded = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise error(f"config file {path!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as problem:
        raise error(f"config file {path!r} cannot be read: {problem}") from None
    except json.JSONDecodeError as problem:
        raise error(f"config file {path!r} is not JSON: {problem}") from None
    if not isinstance(loaded, dict):
        raise error(f"config file {path!r} does not hold a JSON object")
    return loaded

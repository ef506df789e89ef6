"""Docstring examples and documentation links.

* **Doctests.** Every ``>>>`` example in the docstrings of :data:`DOCTEST_MODULES`
  runs under ``make test`` (a module without examples passes), compared with
  pytest's ``doctest_optionflags`` (``pyproject.toml``: ``...`` matches
  anything, runs of white space are equal). Add a module to the list to have
  its examples run; keep them to small pure functions.
* **Links.** Every relative link of ``README.md`` and of the documentation
  pages names a file of the repository, so that they work on GitHub as in the
  site (``make docs`` checks the site's own links in strict mode).
"""

from __future__ import annotations

import doctest
import importlib
import re
from pathlib import Path

import pytest

#: The modules whose docstring examples run as tests.
DOCTEST_MODULES = (
    "amaze.maze.spec",
    "amaze.curriculum.replay",
    "amaze.curriculum.difficulty",
    "amaze.curriculum.distance",
    "amaze.validation",
    "amaze.agents.rewards",
    "amaze.curriculum.regimes",
)
ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINK = re.compile(r"!?\[[^\]\n]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^```.*?^```", re.DOTALL | re.MULTILINE)


@pytest.fixture
def doctest_flags(pytestconfig: pytest.Config) -> int:
    """The flags of ``doctest_optionflags`` in the pytest configuration."""
    flags = 0
    for name in pytestconfig.getini("doctest_optionflags"):
        flags |= doctest.OPTIONFLAGS_BY_NAME[name]
    return flags


@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples(name: str, doctest_flags: int) -> None:
    module = importlib.import_module(name)
    runner = doctest.DocTestRunner(optionflags=doctest_flags)
    report: list[str] = []
    for test in doctest.DocTestFinder().find(module, name):
        runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)


def test_doctest_examples_are_found(doctest_flags: int) -> None:
    """The mechanism itself: an example in a docstring is found, run and compared."""

    def double(x: int) -> list[int]:
        """``x`` twice.

        >>> double(21)
        [21,   21]
        """
        return [x, x]

    assert doctest_flags & doctest.NORMALIZE_WHITESPACE
    runner = doctest.DocTestRunner(optionflags=doctest_flags)
    for test in doctest.DocTestFinder().find(double, "double", globs={"double": double}):
        runner.run(test, out=lambda _: None)
    assert (runner.tries, runner.failures) == (1, 0)


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_relative_links_name_repository_files(page: Path) -> None:
    text = FENCE.sub("", page.read_text(encoding="utf-8"))
    broken = []
    for target in LINK.findall(text):
        if "://" in target or target.startswith(("#", "mailto:")):
            continue
        path = target.partition("#")[0]
        if path and not (page.parent / path).exists():
            broken.append(target)
    assert not broken, f"links to no file: {broken}"

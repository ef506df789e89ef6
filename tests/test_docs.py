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


# -- the site's option tables (docs/hooks/site.py) -------------------------------------------------


@pytest.fixture(scope="module")
def hooks():
    """The site's hook module, loaded from its file (``site`` is the standard library's name)."""
    spec = importlib.util.spec_from_file_location("docs_site_hooks", ROOT / "docs/hooks/site.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def option_tables(hooks) -> dict[str, str]:
    """Every kind of generated table, as Markdown, by the marker that makes it."""
    tables = {
        f"options: {spec}": hooks.options_table(hooks._load(spec))
        for spec in (
            "evolution.config:EvolveConfig",
            "rl_baselines.config:TrainConfig",
            "amaze.runs.config:RunConfig",
        )
    }
    for spec in ("evolution.cli:COMMAND", "rl_baselines.cli:COMMAND"):
        tables[f"run-options: {spec}"] = hooks.run_options_table(hooks._object(spec))
    for spec in (
        "evolution.cmaes:CMAESConfig",
        "amaze.curriculum.maze_population:MazePopulationConfig",
    ):
        tables[f"fields: {spec}"] = hooks.fields_table(hooks._load(spec))
    for regime in ("direct", "edhucat", "coevolution"):
        tables[f"regime-options: {regime}"] = hooks.regime_table(regime)
    tables["regime-matrix"] = hooks.regime_matrix()
    return tables


def rendered_rows(markdown_table: str) -> list[list[str]]:
    """The table as the site's Markdown renders it: each body row's cells, as HTML."""
    import markdown

    html = markdown.markdown(markdown_table, extensions=["tables", "attr_list"])
    rows = re.findall(r"<tr>(.*?)</tr>", html, re.DOTALL)[1:]  # the header row left out
    return [re.findall(r"<td[^>]*>(.*?)</td>", row, re.DOTALL) for row in rows]


def text(cell: str) -> str:
    """A rendered cell as a reader sees it: no tags, entities read."""
    from html import unescape

    return unescape(re.sub(r"<[^>]+>", "", re.sub(r"<br\s*/?>", " ", cell))).strip()


def test_option_tables_show_no_null_default(hooks) -> None:
    """A default of None is the help's own words, a dash or nothing, never JSON's ``null``."""
    tables = option_tables(hooks)
    for marker, table in tables.items():
        for cells in rendered_rows(table):
            assert "null" not in cells[1], (marker, cells[:2])
    run_options = {
        text(cells[0]).split()[0]: text(cells[1])
        for cells in rendered_rows(tables["run-options: rl_baselines.cli:COMMAND"])
    }
    assert run_options["--out"] == ""  # a flag without a default: nothing
    assert run_options["--workers"].startswith("one per core")  # the help's "(default: ...)"
    assert run_options["--replicates"] == "1"
    evolve = {
        text(cells[0]).split()[0]: [text(cell) for cell in cells[1:]]
        for cells in rendered_rows(tables["options: evolution.config:EvolveConfig"])
    }
    assert evolve["curator"][0] == "careful"  # moved out of the help's "(default: careful)"
    assert "(default: careful)" not in evolve["curator"][2]
    assert evolve["advisor"][0] == "\u2014"  # no default in words either: a dash
    assert evolve["robot"][0] == '"DD"'


def test_option_tables_never_break_a_flag_inside_itself(hooks) -> None:
    """Every flag, key and metavar of a first column is an unbreakable piece of code."""
    from html import unescape

    pieces = set()
    for marker, table in option_tables(hooks).items():
        for cells in rendered_rows(table):
            first = cells[0]
            assert "<em>" not in first and "<strong>" not in first, (marker, first)
            codes = re.findall(r"<code([^>]*)>(.*?)</code>", first, re.DOTALL)
            assert codes, (marker, first)
            for attributes, inner in codes:
                assert 'class="unbroken"' in attributes, (marker, first)
                assert not re.sub(r"<span>[^<]*</span>|<wbr>|\s", "", inner), (marker, inner)
                pieces |= {unescape(p) for p in re.findall(r"<span>([^<]*)</span>", inner)}
    assert {"--budget-steps", "budget_steps", "A,B,...", "--no-final-training"} <= pieces
    assert {"{a2c,ppo}", "{local,ray}"} <= pieces  # a short list of choices stays whole
    assert {"{direct,", "edens-populations}"} <= pieces  # a long one breaks after its commas
    assert not any(" " in piece for piece in pieces)
    css = (ROOT / "docs/stylesheets/extra.css").read_text(encoding="utf-8")
    rule = re.search(r"code\.unbroken\s*>\s*span\s*\{([^}]*)\}", css)
    assert rule and "white-space: nowrap" in rule.group(1)
    assert "stylesheets/extra.css" in (ROOT / "mkdocs.yml").read_text(encoding="utf-8")


# -- the training commands of the documentation ---------------------------------------------------

#: A documented command line of a training command: in a shell block (``\`` continues a
#: line; ``#`` starts a comment) or in inline code.
TRAINING = re.compile(r"^(?:\$ )?(amaze-(?:train|evolve))\s+(.*)$")
SHELL_FENCE = re.compile(r"^```(?:sh|bash|shell|console)\n(.*?)^```", re.DOTALL | re.MULTILINE)
INLINE_CODE = re.compile(r"`(amaze-(?:train|evolve)\s[^`]*)`")
#: Options that make an inline command a whole run rather than the mention of an option.
RUN_OPTIONS = ("--budget-steps", "--budget-seconds", "--seed", "--replicates")
#: Curators of the pages' own plug-in examples (docs/curators.md): not installed here, so
#: their commands are checked with a shipped curator in their place.
PLUG_IN_CURATORS = {"mine": "careful"}


def documented_commands() -> list[tuple[str, str, str, bool]]:
    """(page, program, arguments, in a shell block) of every training command of the docs."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        name = page.relative_to(ROOT).as_posix()
        for block in SHELL_FENCE.findall(text):
            for line in block.replace("\\\n", " ").splitlines():
                match = TRAINING.match(line.split(" #")[0].strip())
                if match:
                    found.append((name, match[1], match[2].strip(), True))
        for code in INLINE_CODE.findall(FENCE.sub("", text).replace("\n", " ")):
            program, _, arguments = code.partition(" ")
            found.append((name, program, " ".join(arguments.split()), False))
    return found


COMMANDS = documented_commands()


def test_the_documentation_has_training_commands() -> None:
    shell = [c for c in COMMANDS if c[3]]
    assert len(shell) >= 20
    # the paper's Table 3 row, docs/trainers/rl.md
    assert any(
        "--replicates 10" in arguments and "--out" in arguments for _, _, arguments, _ in shell
    )


@pytest.mark.parametrize(
    ("page", "program", "arguments", "shell"),
    COMMANDS,
    ids=[f"{page}:{program} {arguments}"[:90] for page, program, arguments, _ in COMMANDS],
)
def test_documented_training_commands_run_as_written(
    page: str, program: str, arguments: str, shell: bool
) -> None:
    """A command to copy names its run folder (``--out``; the commands refuse to run
    without one) and, in a shell block, is accepted by the command's own parser and config."""
    argv = arguments.split()
    names = {token.split("=", 1)[0] for token in argv}
    if not shell and not names & set(RUN_OPTIONS):
        return  # the mention of an option (`amaze-evolve --regime coevolution`), not a run
    if names & {"--help", "-h", "--version"}:
        return
    assert names & {"--out", "--resume"}, f"{page}: `{program} {arguments}` has no --out"
    if not shell:
        return
    module = {"amaze-train": "rl_baselines.cli", "amaze-evolve": "evolution.cli"}[program]
    command = importlib.import_module(module).COMMAND
    argv = [PLUG_IN_CURATORS.get(token, token) for token in argv]
    try:
        args = command.parser().parse_args(argv)
    except SystemExit as refused:
        pytest.fail(f"{page}: `{program} {arguments}` is refused by its parser ({refused})")
    if args.resume or args.replay or args.config:
        return  # these read a run folder or a file the page made earlier
    config = command.config()
    config.from_dict(config.from_file_and_arguments(args, None)).validate()


# -- one name for R̄ ----------------------------------------------------------------------------

#: What a reader sees of the project: the pages, the reports, the browser page, the CLI.
READER_FILES = [
    *PAGES,
    *sorted((ROOT / "experiments").rglob("*.py")),
    *sorted((ROOT / "experiments" / "results").rglob("*.md")),
    *sorted((ROOT / "experiments" / "curate" / "static").glob("*.js")),
    *sorted((ROOT / "experiments" / "curate" / "templates").glob("*.html")),
    ROOT / "amaze" / "cli" / "main.py",
]
#: Other names the paper's normalized reward went by: R̄ ("normalized reward R̄" in full,
#: as the ``normalized_reward`` columns) is the one a reader meets.
OTHER_NAMES = re.compile(r"paper(?:'s)? reward|normalised reward R|reward \(paper\)", re.IGNORECASE)


def test_r_bar_has_one_name_wherever_a_reader_sees_it() -> None:
    found = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for path in READER_FILES
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
        if OTHER_NAMES.search(line)
    ]
    assert not found, "\n".join(found)

"""MkDocs hooks of the amaze-evo site: pages made from the repository's own sources.

* **Home**: ``index.md`` is the README, its links rewritten for the site.
* **Option tables**: a page says where a table goes with an HTML comment
  (invisible on GitHub), and the table is built from the config classes
  themselves (``dataclasses.fields``: name, ``help``, ``regimes``, default,
  choices; the command-line flag from the class's own ``add_arguments``):

  * ``<!-- options: evolution.config:EvolveConfig -->``: every option of a
    trainer's config;
  * ``<!-- regime-options: edhucat -->``: the options that act only in some
    regimes and act in this one, for both trainers;
  * ``<!-- regime-matrix -->``: those options against every regime;
  * ``<!-- run-options: evolution.cli:COMMAND -->``: a training command's
    own options (its parser's "run" group: ``--out``, ``--resume``...);
  * ``<!-- fields: evolution.cmaes:CMAESConfig -->``: the fields of a plain
    dataclass (name, type, default).

  A default of ``None`` shows as the help's own "(default: ...)" words, moved
  out of the help, or as a dash (a command's option: as nothing); never as
  ``null``. Flags, keys and metavars are code that breaks between its words
  only (:func:`_code`), never at a dash or a comma inside one.

* **API reference**: one page per public module of the packages
  (``::: module``, rendered by mkdocstrings), listed in the navigation in
  place of the ``reference/api/index.md`` entry.
* **Repository files**: ``CHANGELOG.md`` and the study reports under
  ``experiments/results/`` become pages; a link from a page to another file
  of the repository (``../amaze/maze/spec.py``, right on GitHub) points to
  its page when it has one (a module's source or a package's folder: its API
  page) and is shown as the file's path otherwise. A link to a file that
  does not exist is left as it is, for MkDocs to report.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import importlib
import json
import os
import posixpath
import re
from pathlib import Path
from typing import Any

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files
from mkdocs.structure.pages import Page

ROOT = Path(__file__).resolve().parents[2]
#: The packages of the API reference.
PACKAGES = ("amaze", "evolution", "rl_baselines", "experiments")
#: Where the API pages go, and the navigation entry they replace.
API_DIR = "reference/api"
API_INDEX = f"{API_DIR}/index.md"
#: Repository files shown as pages: repository path -> page.
MIRRORED_FILES = {"CHANGELOG.md": "changelog.md"}
#: Repository folders shown as site folders: repository folder -> site folder.
MIRRORED_FOLDERS = {"experiments/results": "results"}
#: The trainers' configs, for the regime tables: (import path, command).
TRAINERS = (
    ("evolution.config:EvolveConfig", "amaze-evolve"),
    ("rl_baselines.config:TrainConfig", "amaze-train"),
)

ROLE = re.compile(r":[a-z]+:`(?P<tilde>~?)!?(?P<target>[^`]+)`")
MARKER = re.compile(r"^<!--\s*(?P<kind>[a-z-]+)(?::\s*(?P<args>.*?))?\s*-->\s*$", re.MULTILINE)
LINK = re.compile(r"(?P<text>!?\[[^\]\n]*\])\((?P<target>[^)\s]+)(?P<title>\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)


# -- API reference -------------------------------------------------------------


@functools.cache
def api_modules() -> tuple[str, ...]:
    """The public modules of the packages: no ``__main__``, no name starting with ``_``."""
    modules = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            if any(part.startswith("_") for part in parts):
                continue
            modules.append(".".join(parts))
    return tuple(sorted(modules, key=lambda name: name.split(".")))


def _api_page(module: str) -> str:
    return f"{API_DIR}/{module}.md"


def _first_line(module: str) -> str:
    """The first line of a module's docstring, read without importing it, roles as code."""
    base = ROOT.joinpath(*module.split("."))
    path = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
    docstring = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    line = docstring.strip().splitlines()[0] if docstring.strip() else ""

    def code(role: re.Match[str]) -> str:
        target = role["target"]
        return f"`{target.rsplit('.', 1)[-1] if role['tilde'] else target}`"

    return ROLE.sub(code, line)


def _api_nav(modules: tuple[str, ...]) -> list[Any]:
    nav: list[Any] = [API_INDEX]
    for package in PACKAGES:
        nav.append({package: [{m: _api_page(m)} for m in modules if m.split(".")[0] == package]})
    return nav


def _api_index(modules: tuple[str, ...]) -> str:
    lines = [
        "# API reference",
        "",
        "Every public module of the four packages, from its docstrings. The packages and",
        "the import rule between them are described in [the architecture](../../architecture.md).",
        "",
    ]
    for package in PACKAGES:
        lines += [f"## `{package}`", "", "| module | what |", "|---|---|"]
        for module in modules:
            if module.split(".")[0] == package:
                what = _first_line(module).replace("|", "\\|")
                lines.append(f"| [`{module}`]({module}.md) | {what} |")
        lines.append("")
    return "\n".join(lines)


# -- hooks ---------------------------------------------------------------------


def on_config(config: MkDocsConfig) -> MkDocsConfig:
    """Put the API pages into the navigation, in place of its index entry."""
    modules = api_modules()

    def expand(items: list[Any]) -> bool:
        for i, item in enumerate(items):
            if isinstance(item, dict):
                ((title, value),) = item.items()
                if value == API_INDEX:
                    items[i] = {title: _api_nav(modules)}
                    return True
                if isinstance(value, list) and expand(value):
                    return True
        return False

    if not expand(config.nav or []):
        raise PluginError(f"the navigation has no entry for {API_INDEX}")
    return config


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add the pages made from repository files and the API pages."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    files.append(File.generated(config, "index.md", content=_readme_for_site(readme, config)))
    for source, page in MIRRORED_FILES.items():
        files.append(File.generated(config, page, abs_src_path=str(ROOT / source)))
    for source, folder in MIRRORED_FOLDERS.items():
        for path in sorted((ROOT / source).rglob("*")):
            if path.is_file():
                uri = posixpath.join(folder, path.relative_to(ROOT / source).as_posix())
                files.append(File.generated(config, uri, abs_src_path=str(path)))
    modules = api_modules()
    files.append(File.generated(config, API_INDEX, content=_api_index(modules)))
    for module in modules:
        files.append(File.generated(config, _api_page(module), content=f"::: {module}\n"))
    return files


def on_page_markdown(markdown: str, page: Page, config: MkDocsConfig, files: Files) -> str:
    """Expand the option-table markers and point links to repository files at the site."""
    if page.file.src_uri.startswith(API_DIR + "/"):
        return markdown
    return _outside_fences(markdown, lambda text: _links(_markers(text), page, config))


# -- README as the home page ----------------------------------------------------


def _readme_for_site(readme: str, config: MkDocsConfig) -> str:
    """The README with its links made relative to the documentation folder."""
    docs = Path(config.docs_dir)

    def relink(match: re.Match[str]) -> str:
        target = match["target"]
        if _external(target):
            return match[0]
        path, _, anchor = target.partition("#")
        moved = os.path.relpath(ROOT / path, docs).replace(os.sep, "/")
        moved += f"#{anchor}" if anchor else ""
        return f"{match['text']}({moved}{match['title'] or ''})"

    return _outside_fences(readme, lambda text: LINK.sub(relink, text))


# -- links to repository files ---------------------------------------------------


def _external(target: str) -> bool:
    return target.startswith(("#", "/", "mailto:")) or "://" in target


def _links(markdown: str, page: Page, config: MkDocsConfig) -> str:
    docs = Path(config.docs_dir).resolve()
    here = posixpath.dirname(page.file.src_uri)

    def relink(match: re.Match[str]) -> str:
        target = match["target"]
        if _external(target):
            return match[0]
        path, _, anchor = target.partition("#")
        absolute = (docs / here / path).resolve()
        if absolute.is_relative_to(docs) or not absolute.is_relative_to(ROOT):
            return match[0]
        source = absolute.relative_to(ROOT).as_posix()
        site = MIRRORED_FILES.get(source) or _module_page(source)
        for folder, into in MIRRORED_FOLDERS.items():
            if source == folder or source.startswith(folder + "/"):
                site = into + source[len(folder) :]
        if site is not None:
            moved = posixpath.relpath(site, here or ".") + (f"#{anchor}" if anchor else "")
            return f"{match['text']}({moved}{match['title'] or ''})"
        if not absolute.exists():
            return match[0]  # broken: MkDocs reports it
        text = match["text"][1:-1]
        shown = f"`{source}`"
        return shown if text.strip("`") == source or not text else f"{text} ({shown})"

    return LINK.sub(relink, markdown)


def _module_page(source: str) -> str | None:
    """The API page of a module's source file or a package's folder, if it has one."""
    parts = source.removesuffix("/").removesuffix(".py").split("/")
    if parts[-1] == "__init__":
        parts.pop()
    module = ".".join(parts)
    return _api_page(module) if module in api_modules() else None


def _outside_fences(markdown: str, change: Any) -> str:
    """``change`` applied to the text outside fenced code blocks."""
    out, last = [], 0
    for fence in FENCE.finditer(markdown):
        out += [change(markdown[last : fence.start()]), fence[0]]
        last = fence.end()
    out.append(change(markdown[last:]))
    return "".join(out)


# -- option tables ---------------------------------------------------------------


def _markers(markdown: str) -> str:
    def expand(match: re.Match[str]) -> str:
        kind, args = match["kind"], (match["args"] or "").split()
        try:
            if kind == "options" and len(args) == 1:
                return options_table(_load(args[0]))
            if kind == "regime-options" and len(args) == 1:
                return regime_table(args[0])
            if kind == "regime-matrix" and not args:
                return regime_matrix()
            if kind == "fields" and len(args) == 1:
                return fields_table(_load(args[0]))
            if kind == "run-options" and len(args) == 1:
                return run_options_table(_object(args[0]))
        except (ImportError, AttributeError, ValueError) as problem:
            raise PluginError(f"{match[0]}: {problem}") from problem
        if kind in ("options", "regime-options", "regime-matrix", "fields", "run-options"):
            raise PluginError(f"bad marker {match[0]}")
        return match[0]

    return MARKER.sub(expand, markdown)


def _object(spec: str) -> Any:
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def _load(spec: str) -> type:
    cls = _object(spec)
    if not dataclasses.is_dataclass(cls):
        raise ValueError(f"{spec} is not a dataclass")
    return cls


def _default(field: dataclasses.Field) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return dataclasses.MISSING


#: What a table shows for a default that is ``None`` and a help that gives none in words.
NO_DEFAULT = "\u2014"
#: A help's own default, "(default: ...)" or "...; default: ...)": moved to the default column.
HELP_DEFAULT = re.compile(
    r"\s*\(default: (?P<words>[^()]*)\)"  # a parenthesis of its own
    r"|;\s*default: (?P<clause>[^()]*?)(?=\)|$)"  # the last clause, of the help or of a parenthesis
)


def _json(value: Any, help_default: str | None = None) -> str:
    """A default as the table shows it: JSON in code; ``None`` as the help's own default or a dash.

    A field whose default is ``None`` is set by the run (the help says how, in
    its "(default: ...)" words) or is simply absent: JSON's ``null`` would
    mean nothing to a reader.
    """
    if value is dataclasses.MISSING:
        return "*required*"
    if value is None:
        return _cell(help_default) if help_default else NO_DEFAULT
    text = json.dumps(value, default=str)
    return f"`{text}`"


def _help_default(text: str) -> tuple[str | None, str]:
    """The default a help gives in words (or ``None``), and the help without it."""
    match = HELP_DEFAULT.search(text)
    if match is None:
        return None, text
    words = (match["words"] or match["clause"]).strip()
    return words, (text[: match.start()] + text[match.end() :]).strip()


def _cell(text: str) -> str:
    text = " ".join(text.split()).replace("|", "\\|")
    return text.replace("<", "&lt;").replace(">", "&gt;")


#: Characters written as entities inside :func:`_code`: HTML's own, the table's ``|``, and
#: Markdown's emphasis and code marks (the text between raw tags is still Markdown).
CODE_ENTITIES = {c: f"&#{ord(c)};" for c in "&<>|_*`\\[]"}


#: A list of choices longer than this may break after its commas (a short one stays whole).
LONG_CHOICES = 24


def _code(text: str) -> str:
    """``text`` as inline code that wraps between its words only, never inside one.

    A flag (``--budget-steps``), a key (``budget_steps``) or a metavar
    (``A,B,...``) is one unbreakable piece (``white-space: nowrap``, see
    ``docs/stylesheets/extra.css``), so that a narrow column breaks it at a
    space, never at its dashes or commas. A long list of choices
    (``{direct,interpolation,...}``) may break after its commas, each choice
    kept whole.
    """
    words = []
    for word in text.split():
        if word.startswith("{") and word.endswith("}") and len(word) > LONG_CHOICES:
            parts = [part + "," for part in word.split(",")]
            parts[-1] = parts[-1][:-1]
        else:
            parts = [word]
        words.append("<wbr>".join(f"<span>{_escaped(part)}</span>" for part in parts))
    return f'<code class="unbroken">{" ".join(words)}</code>'


def _escaped(text: str) -> str:
    return "".join(CODE_ENTITIES.get(c, c) for c in text)


def _flag(action: argparse.Action) -> str:
    """An option as ``--help`` shows it: ``--name METAVAR``, ``--x / --no-x``."""
    if isinstance(action, argparse.BooleanOptionalAction):
        return " / ".join(_code(flag) for flag in action.option_strings)
    if action.nargs == 0:
        return _code(action.option_strings[0])
    metavar = action.metavar or (
        "{" + ",".join(action.choices) + "}" if action.choices else action.dest.upper()
    )
    return _code(f"{action.option_strings[0]} {metavar}")


def _flags(cls: type) -> dict[str, tuple[str, str]]:
    """The command-line form of each option, as the class's ``add_arguments`` declares it."""
    parser = argparse.ArgumentParser(add_help=False)
    cls.add_arguments(parser)
    return {
        action.dest: (_flag(action), action.help or "")
        for action in parser._actions
        if action.option_strings
    }


def run_options_table(command: Any) -> str:
    """A training command's own options: the "run" group of its parser."""
    groups = [g for g in command.parser()._action_groups if g.title == "run"]
    if not groups:
        raise ValueError(f"{command!r} has no group of run options")
    rows = ["| option | default | what it does |", "|---|---|---|"]
    for action in groups[0]._group_actions:
        words, help_text = _help_default(action.help or "")
        if action.default not in (None, argparse.SUPPRESS):
            default, help_text = f"`{action.default}`", action.help or ""
        else:  # no default: the help's words for what happens, else nothing
            default = _cell(words or "")
        rows.append(f"| {_flag(action)} | {default} | {_cell(help_text)} |")
    return "\n".join(rows) + "\n"


def _what(field: dataclasses.Field) -> str:
    text = field.metadata.get("help", "")
    if _default(field) is None:  # its default in words goes to the default column
        text = _help_default(text)[1]
    text = _cell(text)
    choices = field.metadata.get("choices")
    if choices:
        text += "; one of " + ", ".join(_code(str(c)) for c in choices)
    return text


def _field_default(field: dataclasses.Field) -> str:
    """The default column of a field: its JSON, or for ``None`` its help's words or a dash."""
    return _json(_default(field), _help_default(field.metadata.get("help", ""))[0])


def _regimes(field: dataclasses.Field) -> str:
    regimes = field.metadata.get("regimes")
    return "every regime" if regimes is None else ", ".join(_code(r) for r in regimes)


def options_table(cls: type) -> str:
    """Every option of a run config: its flag, ``config.json`` key, default, regimes, help."""
    flags = _flags(cls) if hasattr(cls, "add_arguments") else {}
    rows = [
        "| `config.json` key<br>command line | default | acts in | what it does |",
        "|---|---|---|---|",
    ]
    names = set()
    for field in dataclasses.fields(cls):
        names.add(field.name)
        rows.append(
            f"| {_option(field, flags)} | {_field_default(field)} | {_regimes(field)}"
            f" | {_what(field)} |"
        )
    for dest, (flag, help_text) in flags.items():
        if dest not in names:  # an option of the command that is not a field
            words, help_text = _help_default(help_text)
            rows.append(f"| {flag} | {_cell(words or '')} | every regime | {_cell(help_text)} |")
    return "\n".join(rows) + "\n"


def _option(field: dataclasses.Field, flags: dict[str, tuple[str, str]]) -> str:
    """A field's ``config.json`` key above its command-line form."""
    flag = flags[field.name][0] if field.name in flags else f"(in the {_code('--config')} file)"
    return f"{_code(field.name)}<br>{flag}"


def _trainers() -> list[tuple[type, str]]:
    return [(_load(spec), command) for spec, command in TRAINERS]


def regime_table(regime: str) -> str:
    """The options that act in some regimes only, this one among them, in both trainers."""
    trainers = _trainers()
    known = {r for cls, _ in trainers for r in cls.supported_regimes}
    if regime not in known:
        raise ValueError(f"unknown regime {regime!r} (known: {', '.join(sorted(known))})")
    found: dict[str, tuple[dataclasses.Field, list[str], str]] = {}
    for cls, command in trainers:
        flags = _flags(cls)
        for field in dataclasses.fields(cls):
            regimes = field.metadata.get("regimes")
            if regimes is None or regime not in regimes or regime not in cls.supported_regimes:
                continue
            entry = found.setdefault(field.name, (field, [], _option(field, flags)))
            entry[1].append(_code(command))
    rows = [
        "| `config.json` key<br>command line | default | also acts in | trainers | what it does |",
        "|---|---|---|---|---|",
    ]
    for field, commands, option in found.values():
        others = [_code(r) for r in field.metadata["regimes"] if r != regime]
        rows.append(
            f"| {option} | {_field_default(field)} | {', '.join(others) or NO_DEFAULT}"
            f" | {', '.join(commands)} | {_what(field)} |"
        )
    return "\n".join(rows) + "\n"


def regime_matrix() -> str:
    """Which regime-bound option acts in which regime (both trainers)."""
    trainers = _trainers()
    regimes: list[str] = []
    for cls, _ in trainers:
        regimes += [r for r in cls.supported_regimes if r not in regimes]
    fields: dict[str, dataclasses.Field] = {}
    for cls, _ in trainers:
        for field in dataclasses.fields(cls):
            if field.metadata.get("regimes") is not None:
                fields.setdefault(field.name, field)
    rows = [
        "| option | " + " | ".join(_code(r) for r in regimes) + " |",
        "|---|" + "---|" * len(regimes),
    ]
    for name, field in fields.items():
        marks = ["yes" if r in field.metadata["regimes"] else "" for r in regimes]
        rows.append(f"| {_code(name)} | " + " | ".join(marks) + " |")
    return "\n".join(rows) + "\n"


def fields_table(cls: type) -> str:
    """The fields of a plain dataclass: name, type and default."""
    rows = ["| key | type | default |", "|---|---|---|"]
    for field in dataclasses.fields(cls):
        kind = field.type if isinstance(field.type, str) else getattr(field.type, "__name__", "")
        rows.append(f"| {_code(field.name)} | {_cell(str(kind))} | {_json(_default(field))} |")
    return "\n".join(rows) + "\n"

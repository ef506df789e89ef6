"""Griffe extension: the project's Sphinx-style docstrings, rendered by mkdocstrings.

The docstrings are written for Sphinx: roles such as :class:`~a.b.C`,
``literal`` text and ``::`` before literal blocks. This extension rewrites
them, once each package is loaded, into the Markdown that mkdocstrings and
mkdocs-autorefs understand:

* a role naming an object of the project becomes a cross-reference,
  ``[`C`][a.b.C]`` (``~`` shows the last name only, ``!`` or a private name
  shows the text as code). A name without a package is resolved the way
  Python would in the docstring's scope (a member, a module-level name, an
  import). A reference that points nowhere in the project is left for
  mkdocs-autorefs to report, which fails a ``--strict`` build;
* a role naming anything else (the standard library, numpy...) becomes code;
* ``Text::`` becomes ``Text:`` and a line holding only ``::`` is dropped (the
  indented block after it is a Markdown code block as it stands);
* a doctest block (lines from one starting with ``>>>`` to the next blank
  line) becomes a fenced ``pycon`` code block, not a Markdown quotation;
* an attribute documented by ``#:`` comments above it (Sphinx's form) gets
  them as its docstring, and a config field declared with
  ``amaze.runs.config.option(default, help)`` gets its help text.

Options (``mkdocs.yml``): ``packages``, the top-level packages whose objects
are linked, and ``moved``, references known to name an object that has moved
since the docstring was written: each full dotted path, as written, with the
path it now has (or ``null`` to show it as code), until the docstring is fixed.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

import griffe

#: A Sphinx role: :role:`target`, :role:`~target`, :role:`title <target>`.
ROLE = re.compile(
    r":(?:py:)?(?P<role>class|func|meth|mod|data|attr|exc|obj|const|type)"
    r":`(?P<body>[^`]+)`"
)
#: What griffe raises for a name it cannot resolve in a scope.
UNRESOLVED = (griffe.NameResolutionError, griffe.AliasResolutionError, griffe.CyclicAliasError)
#: ``Text::`` at the end of a line (a literal block follows).
LITERAL_MARKER = re.compile(r"(?<=\S)::[ \t]*$", re.MULTILINE)
#: A line holding only ``::``.
LITERAL_LINE = re.compile(r"^[ \t]*::[ \t]*\n", re.MULTILINE)


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx markup in the docstrings of the listed packages."""

    def __init__(
        self, packages: Iterable[str] = (), moved: Mapping[str, str | None] | None = None
    ) -> None:
        super().__init__()
        self.packages = set(packages)
        self.moved = dict(moved or {})

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        """Rewrite every docstring of a package once it is loaded."""
        if self.packages and pkg.name not in self.packages:
            return
        for obj in _objects(pkg):
            if obj.is_attribute and obj.docstring is None:
                text = _comment_docstring(obj) or _option_help(obj)
                if text:
                    obj.docstring = griffe.Docstring(
                        text,
                        lineno=obj.lineno,
                        parent=obj,
                        parser=pkg.docstring.parser if pkg.docstring else None,
                        parser_options=pkg.docstring.parser_options if pkg.docstring else None,
                    )
            if obj.docstring is not None:
                obj.docstring.value = self.rewrite(obj.docstring.value, obj)

    def rewrite(self, text: str, obj: griffe.Object) -> str:
        """The docstring ``text`` of ``obj`` with its Sphinx markup as Markdown."""
        text = LITERAL_LINE.sub("\n", text)
        text = LITERAL_MARKER.sub(":", text)
        text = ROLE.sub(lambda match: self._role(match, obj), text)
        return _doctest_blocks(text)

    def _role(self, match: re.Match[str], obj: griffe.Object) -> str:
        body = match["body"].strip()
        explicit = re.fullmatch(r"(?P<title>.+?)\s*<(?P<target>[^>]+)>", body, re.DOTALL)
        if explicit:
            title, target, plain = explicit["title"], explicit["target"].strip(), False
        else:
            plain = body.startswith("!")
            target = body.lstrip("~!")
            title = target.rsplit(".", 1)[-1] if body.startswith("~") else target
        path = None if plain else self._resolve(target.removesuffix("()").lstrip("."), obj)
        return f"`{title}`" if path is None else f"[`{title}`][{path}]"

    def _resolve(self, target: str, obj: griffe.Object) -> str | None:
        """The project path ``target`` names in ``obj``'s scope, or ``None`` for code."""
        if target in self.moved:
            return self.moved[target]
        head, _, rest = target.partition(".")
        if head in self.packages:
            path = target
        else:
            try:
                path = obj.resolve(head)
            except UNRESOLVED:
                return None
            if rest:
                path = f"{path}.{rest}"
        parts = path.split(".")
        if path in self.moved:
            return self.moved[path]
        if parts[0] not in self.packages:
            return None  # outside the project: shown as code
        if any(part.startswith("_") and not part.startswith("__") for part in parts):
            return None  # private: not in the reference
        return path


def _doctest_blocks(text: str) -> str:
    """Each doctest block of ``text`` as a fenced ``pycon`` block, at its indentation."""
    lines, out, i = text.split("\n"), [], 0
    while i < len(lines):
        line = lines[i]
        if not line.lstrip().startswith(">>>"):
            out.append(line)
            i += 1
            continue
        indent = line[: len(line) - len(line.lstrip())]
        if out and out[-1].strip():
            out.append("")
        out.append(f"{indent}```pycon")
        while i < len(lines) and lines[i].strip():
            out.append(lines[i])
            i += 1
        out.append(f"{indent}```")
    return "\n".join(out)


def _objects(obj: griffe.Object) -> Iterator[griffe.Object]:
    """``obj`` and every object defined in it (not the names it imports)."""
    yield obj
    for member in obj.members.values():
        if not member.is_alias:
            yield from _objects(member)


def _comment_docstring(attr: griffe.Object) -> str | None:
    """The ``#:`` comment lines right above an attribute, as its docstring."""
    if attr.lineno is None:
        return None
    lines = attr.module.lines
    index = attr.lineno - 2
    found: list[str] = []
    while index >= 0 and lines[index].lstrip().startswith("#:"):
        found.append(lines[index].lstrip()[2:].strip())
        index -= 1
    return "\n".join(reversed(found)) or None


def _option_help(attr: griffe.Object) -> str | None:
    """The help text of a field declared with ``option(default, help, ...)``."""
    value = attr.value
    if not isinstance(value, griffe.ExprCall) or str(value.function).split(".")[-1] != "option":
        return None
    positional = [a for a in value.arguments if not isinstance(a, griffe.ExprKeyword)]
    keywords = {a.name: a.value for a in value.arguments if isinstance(a, griffe.ExprKeyword)}
    source = keywords.get("help", positional[1] if len(positional) > 1 else None)
    try:
        text = ast.literal_eval(str(source))
    except (ValueError, SyntaxError):
        return None
    if not isinstance(text, str) or not text:
        return None
    return text[0].upper() + text[1:] + ("" if text.endswith(".") else ".")

"""Run configs: dataclass fields, documented once, drive the config file and the command line.

A trainer's config (``EvolveConfig``, ``TrainConfig``) subclasses
:class:`RunConfig` and declares each field with :func:`option`::

    budget_steps: int | None = option(3_000_000, "environment steps to spend")

That one declaration gives the ``config.json`` key, the ``--budget-steps``
command-line option with its type, choices and ``--help`` text, and the
default. Values are checked in one place, the config's ``validate``, whether
they come from a file, the command line or Python.

A ``--config FILE.json`` holds either a whole config (every key a field) or,
for convenience, only the options of the field named by
:attr:`RunConfig.options_field` (the SB3 hyperparameters, the search
algorithm's options); command-line options win over the file.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, TypeVar, Union

from amaze.agents.robot import as_robot
from amaze.errors import AmazeError, one_line
from amaze.validation import MAX_JSON_DEPTH, check_integer, closest, nests_within, parse_json

__all__ = [
    "MAX_CONFIG_BYTES",
    "MAX_SEED",
    "MAX_YAML_NODES",
    "RunConfig",
    "config_from_dict",
    "option",
    "read_config_file",
    "read_json_object",
]

#: The largest seed of a run: numpy's and SB3's global seeding take 32-bit seeds.
MAX_SEED = 2**32 - 1
#: The largest config file (JSON or YAML) read: the project's are a few KiB.
MAX_CONFIG_BYTES = 16 * 2**20
#: The most nodes (scalars, lists, mappings) a YAML config may hold once its
#: aliases are expanded: ten nested lists of ten aliases make a few hundred
#: bytes that would expand to billions (the "billion laughs"). The project's
#: configs hold a few hundred; yaml's pure-Python loader spends about 15 us and
#: 700 bytes on a node, so a file is refused within about 1.5 s and 100 MB.
MAX_YAML_NODES = 100_000

_Config = TypeVar("_Config")
_RunConfig = TypeVar("_RunConfig", bound="RunConfig")


def option(
    default: Any = dataclasses.MISSING,
    help: str = "",
    *,
    default_factory: Any = dataclasses.MISSING,
    choices: tuple[str, ...] | None = None,
    command_line: bool = True,
    metavar: str | None = None,
    regimes: tuple[str, ...] | None = None,
) -> Any:
    """A config field with its ``--help`` text (and choices, if any).

    ``command_line=False`` keeps a field out of the command line (a nested
    object such as the hyperparameters, set through ``--config``).
    ``regimes`` names the training regimes in which the field has an effect
    (``None``: every regime); a config of another regime that sets it to
    anything but its default is refused (:meth:`RunConfig.refuse_options_without_effect`).
    """
    metadata = {
        "help": help,
        "choices": choices,
        "command_line": command_line,
        "metavar": metavar,
        "regimes": regimes,
    }
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def config_from_dict(
    cls: type[_Config], data: Any, error: type[ValueError], what: str = "config"
) -> _Config:
    """An instance of the config dataclass ``cls`` from a JSON object.

    Missing keys take their defaults; a value that is not a mapping, or any
    unknown key, raises ``error`` naming it (the fields' own checks are the
    dataclass's business).
    """
    if not isinstance(data, Mapping):
        raise error(f"a {what} must be a JSON object, not {data!r}")
    known = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(known), key=str)
    if unknown:
        named = ", ".join(f"{key!r}{closest(key, known)}" for key in unknown)
        raise error(f"unknown {what} key(s): {named}")
    return cls(**dict(data))


def _read_capped(path: Path, where: str, error: type[ValueError]) -> bytes:
    """The bytes of the file ``path``, refused (``error`` naming ``where``) past
    :data:`MAX_CONFIG_BYTES` before it is read whole."""
    try:
        with open(path, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            data = b"" if size > MAX_CONFIG_BYTES else stream.read(MAX_CONFIG_BYTES + 1)
    except FileNotFoundError:
        raise error(f"{where} does not exist") from None
    except IsADirectoryError:
        raise error(f"{where} is a directory") from None
    except OSError as problem:
        raise error(f"{where} cannot be read: {problem.strerror or problem}") from None
    if max(size, len(data)) > MAX_CONFIG_BYTES:
        amount = f"{size:,}" if size > MAX_CONFIG_BYTES else f"more than {MAX_CONFIG_BYTES:,}"
        raise error(f"{where} is too large: {amount} bytes, at most {MAX_CONFIG_BYTES:,} are read")
    return data


def read_json_object(path: str | Path, error: type[ValueError], what: str = "config file") -> dict:
    """The JSON object in the file ``path``; raise ``error`` naming the file otherwise.

    A file over :data:`MAX_CONFIG_BYTES` is refused before it is read.
    """
    where = f"{what} {str(path)!r}"
    loaded = parse_json(_read_capped(Path(path), where, error), where, error=error)
    if not isinstance(loaded, dict):
        raise error(f"{where} does not hold a JSON object")
    return loaded


def _expanded_nodes(root: Any, budget: int) -> int:
    """The nodes of the YAML node graph ``root`` once its aliases are expanded,
    or ``budget + 1`` as soon as they are more than ``budget`` (a cycle is).

    Each node's count is memoised (by id), so shared nodes cost one visit;
    walked without recursion.
    """
    counts: dict[int, int] = {}
    open_nodes: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, finished = stack.pop()
        if isinstance(node.value, list):  # a sequence's nodes, a mapping's (key, value) pairs
            children = [
                c for item in node.value for c in (item if isinstance(item, tuple) else (item,))
            ]
        else:
            children = []
        if finished:
            count = 1 + sum(counts[id(child)] for child in children)
            if count > budget:
                return budget + 1
            counts[id(node)] = count
            open_nodes.discard(id(node))
        elif id(node) in open_nodes:  # an alias inside its own anchor: infinite
            return budget + 1
        elif id(node) not in counts:
            open_nodes.add(id(node))
            stack.append((node, True))
            stack.extend((child, False) for child in children if id(child) not in counts)
    return counts[id(root)]


def _load_yaml(text: str, where: str, error: type[ValueError]) -> Any:
    """The value of the YAML document ``text`` (``yaml``'s safe constructors), aliases
    expanded under :data:`MAX_YAML_NODES`; ``error`` naming ``where`` otherwise."""
    import yaml

    class BudgetLoader(yaml.SafeLoader):
        """A safe loader that stops composing past the budget of nodes."""

        composed = 0

        def compose_node(self, parent: Any, index: Any) -> Any:
            self.composed += 1
            if self.composed > MAX_YAML_NODES:
                raise error(f"{where} holds more than {MAX_YAML_NODES:,} YAML nodes")
            return super().compose_node(parent, index)

    loader = None
    try:
        loader = BudgetLoader(text)
        node = loader.get_single_node()
        if node is None:
            return None
        if _expanded_nodes(node, MAX_YAML_NODES) > MAX_YAML_NODES:
            raise error(
                f"{where} holds more than {MAX_YAML_NODES:,} YAML nodes once its aliases"
                " are expanded"
            )
        return loader.construct_document(node)
    except yaml.YAMLError as problem:
        raise error(f"{where} is not YAML: {one_line(problem)}") from None
    except RecursionError:
        raise error(f"{where} nests lists or mappings more than {MAX_JSON_DEPTH} deep") from None
    finally:
        if loader is not None:
            loader.dispose()


def read_config_file(path: str | Path, error: type[ValueError]) -> dict:
    """A ``--config`` file's object: YAML for ``.yml``/``.yaml``, JSON otherwise.

    A file over :data:`MAX_CONFIG_BYTES` is refused before it is read. YAML
    is read with ``yaml``'s safe loader (plain data: no tag can build an
    object or run code), its aliases expanded only if the document then
    holds at most :data:`MAX_YAML_NODES` nodes, and held to the rules of
    JSON: nesting at most :data:`~amaze.validation.MAX_JSON_DEPTH` deep, and
    an object at the top.
    """
    path = Path(path)
    if path.suffix.lower() not in (".yml", ".yaml"):
        return read_json_object(path, error)
    where = f"config file {str(path)!r}"
    try:
        text = _read_capped(path, where, error).decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"{where} is not UTF-8 text") from None
    loaded = _load_yaml(text, where, error)
    if not nests_within(loaded, MAX_JSON_DEPTH):
        raise error(f"{where} nests lists or mappings more than {MAX_JSON_DEPTH} deep")
    if not isinstance(loaded, dict):
        raise error(f"{where} does not hold a mapping")
    return loaded


def _option_type(annotation: Any) -> Any:
    """The Python type behind ``int``, ``int | None``, ``list[str]``... (``None`` stripped)."""
    if typing.get_origin(annotation) in (Union, types.UnionType):
        kept = [a for a in typing.get_args(annotation) if a is not type(None)]
        return _option_type(kept[0]) if len(kept) == 1 else str
    return annotation


def _comma_separated(text: str) -> list[str]:
    return [item.strip() for item in text.split(",") if item.strip()]


@dataclasses.dataclass
class RunConfig:
    """Base of the trainers' configs: ``config.json``, the command line and checks.

    Subclasses are dataclasses whose fields are declared with :func:`option`
    and whose :meth:`validate` checks (and normalises) every value, raising
    :attr:`error` with a message naming the bad value.
    """

    #: The error class of the trainer (an :class:`~amaze.errors.AmazeError`).
    error: ClassVar[type[AmazeError]] = AmazeError
    #: The field a ``--config`` file of options alone fills (``None``: whole configs only).
    options_field: ClassVar[str | None] = None

    robot: str = option("DD", "robot: DD, a hybrid (H15) or a continuous (CC15) one")
    seed: int = option(0, "seed of every random draw of the run")

    def validate(self: _RunConfig) -> _RunConfig:
        """Check every field; raise :attr:`error` naming the bad value. Returns ``self``.

        Subclasses check their own fields and call this for the shared ones.
        """
        try:
            self.robot = as_robot(self.robot).to_string()
        except ValueError as problem:
            raise self.error(f"robot {self.robot!r}: {problem}") from None
        self.seed = check_integer("seed", self.seed, minimum=0, maximum=MAX_SEED, error=self.error)
        return self

    @classmethod
    def from_dict(cls: type[_RunConfig], data: Any) -> _RunConfig:
        """A checked config from a JSON object; unknown keys are errors."""
        return config_from_dict(cls, data, cls.error).validate()

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of ``config.json``."""
        return dataclasses.asdict(self)

    def refuse_options_without_effect(self, regime: str) -> None:
        """Refuse every field set away from its default in a ``regime`` where it has no effect.

        A field's ``regimes`` (:func:`option`) say where it acts; an option
        that a run would silently ignore is a mistake worth one clear error.
        """
        for f in dataclasses.fields(self):
            regimes = f.metadata.get("regimes")
            if regimes is None or regime in regimes:
                continue
            value = getattr(self, f.name)
            default = f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
            if value != default:
                flag = f" (--{f.name.replace('_', '-')})" if f.metadata["command_line"] else ""
                raise self.error(
                    f"{f.name}{flag} {value!r} has no effect in the {regime} regime: it is"
                    f" for {', '.join(regimes)}"
                )

    # -- the command line ---------------------------------------------------

    @classmethod
    def command_line_fields(cls) -> list[dataclasses.Field]:
        """The fields that are command-line options, in declaration order."""
        return [f for f in dataclasses.fields(cls) if f.metadata.get("command_line", False)]

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """Add ``--field-name`` for every command-line field, typed and documented."""
        hints = typing.get_type_hints(cls)
        for f in cls.command_line_fields():
            kind = _option_type(hints[f.name])
            flag = "--" + f.name.replace("_", "-")
            default = f.default if f.default is not dataclasses.MISSING else None
            help_text = f.metadata["help"]
            if default is not None:
                help_text = f"{help_text} (default: {default})"
            kwargs: dict[str, Any] = {"help": help_text, "dest": f.name}
            if f.metadata.get("metavar"):
                kwargs["metavar"] = f.metadata["metavar"]
            if kind is bool:
                kwargs["action"] = argparse.BooleanOptionalAction
            elif typing.get_origin(kind) is list:
                kwargs["type"] = _comma_separated
                kwargs.setdefault("metavar", "A,B,...")
            else:
                kwargs["type"] = kind
                if f.metadata.get("choices"):
                    kwargs["choices"] = f.metadata["choices"]
                elif kind in (int, float):
                    kwargs.setdefault("metavar", "N" if kind is int else "X")
            parser.add_argument(flag, **kwargs)

    @classmethod
    def given_extra_options(cls, args: argparse.Namespace) -> list[str]:
        """The flags a subclass's :meth:`add_arguments` adds beyond the fields, given in ``args``.

        (``--resume`` and ``--replay`` refuse them, as the fields' own flags.)
        """
        return []

    @classmethod
    def from_file_and_arguments(
        cls, args: argparse.Namespace, config_file: str | None
    ) -> dict[str, Any]:
        """The config's JSON object from ``--config FILE`` and the command-line options.

        A file with any key that is a field is a whole config (its other keys
        are then refused by name, with the field each one is closest to); a
        file without one holds the options of :attr:`options_field`. Options
        given on the command line win. The result is checked by
        :meth:`from_dict` later.
        """
        data: dict[str, Any] = {}
        if config_file:
            loaded = cls.adapt_config_file(read_config_file(config_file, cls.error))
            names = {f.name for f in dataclasses.fields(cls)}
            if set(loaded) & names or cls.options_field is None:
                data = loaded
            else:
                data = {cls.options_field: loaded}
        for f in cls.command_line_fields():
            value = getattr(args, f.name, None)
            if value is not None:
                data[f.name] = value
        return cls.adjust_command_line(data, args)

    @classmethod
    def adjust_command_line(cls, data: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
        """Hook: trainer-specific meaning of command-line combinations (default: none)."""
        return data

    @classmethod
    def adapt_config_file(cls, loaded: dict[str, Any]) -> dict[str, Any]:
        """Hook: a ``--config`` file in another tool's layout, as this config's (default: as is)."""
        return loaded

"""A state as a JSON document and arrays, and back, calling nothing the document names.

The codec of :mod:`amaze.runs.checkpoint` (whose docstring gives the
document's forms): :class:`StateCodec` holds what a state may hold besides
plain data (the classes and values the trainer's code registers);
:class:`StateWriter` turns a state into a document and its arrays, refusing
anything unregistered; :class:`StateReader` rebuilds the state from them,
refusing anything the codec does not hold (:class:`Refused`), without calling
any class with values from the document.
"""

from __future__ import annotations

import base64
import enum
import math
import sys
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import numpy as np

__all__ = [
    "MAX_STATE_DEPTH",
    "RENAMED_MODULES",
    "ArrayLookup",
    "CheckpointError",
    "Refused",
    "StateCodec",
    "StateReader",
    "StateWriter",
    "current_tag",
    "package_classes",
    "simplified",
    "special_reduce",
    "tag",
]

#: How deep a state may nest (objects inside objects...).
MAX_STATE_DEPTH = 60

#: The bit generators a ``numpy.random.Generator`` in a checkpoint may use.
_BIT_GENERATORS: dict[str, type] = {
    cls.__name__: cls
    for cls in (np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox)
} | {"SFC64": np.random.SFC64}
#: Array element kinds a checkpoint may hold: booleans and numbers.
_ARRAY_KINDS = frozenset("biufc")
#: Modules renamed since checkpoints named them: old name -> new name. A tag of an old
#: module is read as the same qualname in the new one (run folders written before the
#: rename resume).
RENAMED_MODULES: dict[str, str] = {
    "amaze.curriculum.coevolution": "amaze.curriculum.maze_population",
    "rl_baselines.jax_coevolution": "rl_baselines.jax.coevolution",
}


class CheckpointError(TypeError):
    """A state holds a value that a checkpoint cannot write (a programming error)."""


def tag(value: Any) -> str:
    """The tag of a class, function or enumeration: ``module:qualname``."""
    return f"{value.__module__}:{value.__qualname__}"


def current_tag(name: str) -> str:
    """``name``, its module renamed as :data:`RENAMED_MODULES` says (unchanged otherwise)."""
    module, colon, qualname = name.partition(":")
    renamed = RENAMED_MODULES.get(module)
    return f"{renamed}:{qualname}" if colon and renamed is not None else name


def special_reduce(cls: type) -> bool:
    """Whether ``cls`` pickles by a constructor call of its own (which a checkpoint never makes)."""
    return any(
        name in vars(klass)
        for klass in cls.__mro__
        if klass not in (object, dict, list)
        for name in ("__reduce__", "__reduce_ex__", "__getnewargs__", "__getnewargs_ex__")
    )


class StateCodec:
    """What a checkpoint may hold besides plain data: classes and values, registered by code.

    ``classes`` are rebuilt as the module docstring says (enumerations by
    value); ``constants`` are values kept as they are (functions, classes used
    as values). Classes that pickle through a constructor call of their own
    (``__reduce__``, ``__getnewargs__``) cannot be registered: rebuilding them
    would mean calling them.
    """

    def __init__(self, classes: Iterable[type] = (), constants: Iterable[Any] = ()) -> None:
        self.classes: dict[str, type] = {}
        for cls in classes:
            if not isinstance(cls, type):
                raise CheckpointError(f"{cls!r} is not a class")
            if not issubclass(cls, enum.Enum) and special_reduce(cls):
                raise CheckpointError(f"class {tag(cls)} pickles by a constructor call")
            self.classes[tag(cls)] = cls
        self.constants: dict[str, Any] = {tag(value): value for value in constants}
        self._constant_tags = {id(value): name for name, value in self.constants.items()}

    def union(self, other: StateCodec) -> StateCodec:
        """A codec registering what either registers."""
        return StateCodec(
            [*self.classes.values(), *other.classes.values()],
            [*self.constants.values(), *other.constants.values()],
        )

    def constant_tag(self, value: Any) -> str | None:
        """The tag of ``value`` if it is one of the registered constants."""
        name = self._constant_tags.get(id(value))
        return name if name is not None and self.constants[name] is value else None


def package_classes(prefix: str) -> list[type]:
    """Every class defined in the loaded modules of the package ``prefix`` (``"cma"``).

    Classes that pickle by a constructor call of their own are left out: a
    checkpoint never calls a class.
    """
    found: dict[str, type] = {}
    for name, module in list(sys.modules.items()):
        if module is None or not (name == prefix or name.startswith(prefix + ".")):
            continue
        for value in vars(module).values():
            if not (isinstance(value, type) and value.__module__ == name):
                continue
            if issubclass(value, enum.Enum) or not special_reduce(value):
                found[f"{value.__module__}:{value.__qualname__}"] = value
    return list(found.values())


# -- writing -------------------------------------------------------------------------


class StateWriter:
    """Turns a state into a JSON document and a list of arrays."""

    def __init__(self, codec: StateCodec) -> None:
        self.codec = codec
        self.arrays: list[np.ndarray] = []
        self.nodes: dict[int, dict] = {}  # id(object) -> its node, for shared objects
        self.alive: list[Any] = []  # keeps every memoised object alive (ids stay unique)
        self.in_progress: set[int] = set()  # tuples being written (a cycle through one fails)
        self.ids = 0

    def shared(self, value: Any) -> dict | None:
        """A ``$ref`` to ``value`` if it was written before (marking the first node)."""
        node = self.nodes.get(id(value))
        if node is None:
            return None
        if "$id" not in node:
            node["$id"] = self.ids
            self.ids += 1
        return {"$ref": node["$id"]}

    def remember(self, value: Any, node: dict) -> dict:
        self.nodes[id(value)] = node
        self.alive.append(value)
        return node

    def write(self, value: Any, where: str, depth: int = 0) -> Any:
        if depth > MAX_STATE_DEPTH:
            raise CheckpointError(f"{where}: the state nests more than {MAX_STATE_DEPTH} deep")
        kind = type(value)
        if value is None or kind in (bool, int, str):
            return value
        if kind is float:
            return value if math.isfinite(value) else {"$float": repr(value)}
        constant = self.codec.constant_tag(value)
        if constant is not None:
            return {"$constant": constant}
        if isinstance(value, enum.Enum):
            return self.enum(value, where, depth)
        if kind is bytes:
            return {"$bytes": base64.b64encode(value).decode("ascii")}
        if kind is tuple or kind is frozenset:
            return self.immutable(value, where, depth)
        shared = self.shared(value)
        if shared is not None:
            return shared
        if kind is list:
            node = self.remember(value, {"$list": []})
            node["$list"] = [self.write(v, f"{where}[{i}]", depth + 1) for i, v in enumerate(value)]
            return node
        if kind is dict:
            node = self.remember(value, {"$dict": []})
            node["$dict"] = self.pairs(value, where, depth)
            return node
        if kind is defaultdict:
            return self.defaultdict(value, where, depth)
        if kind is set:
            node = self.remember(value, {"$set": []})
            node["$set"] = [self.write(v, f"{where}{{}}", depth + 1) for v in _ordered(value)]
            return node
        if isinstance(value, np.ndarray | np.generic):
            return self.remember(value, self.array(value, where))
        if kind is np.random.Generator:
            return self.remember(value, self.generator(value, where))
        if isinstance(value, np.dtype):
            return {"$dtype": _checked_dtype(value, where, CheckpointError).str}
        return self.object(value, where, depth)

    def pairs(self, value: dict, where: str, depth: int) -> list:
        return [
            [self.write(k, f"{where} key", depth + 1), self.write(v, f"{where}[{k!r}]", depth + 1)]
            for k, v in value.items()
        ]

    def defaultdict(self, value: defaultdict, where: str, depth: int) -> dict:
        factory = value.default_factory
        if factory is not None and self.codec.constant_tag(factory) is None:
            raise CheckpointError(f"{where}: the factory {factory!r} is not registered")
        node = self.remember(value, {"$defaultdict": self.write(factory, where, depth + 1)})
        node["items"] = self.pairs(value, where, depth)
        return node

    def immutable(self, value: tuple | frozenset, where: str, depth: int) -> dict:
        if id(value) in self.in_progress:
            raise CheckpointError(f"{where}: a cycle through a tuple cannot be written")
        self.in_progress.add(id(value))
        items = value if type(value) is tuple else _ordered(value)
        written = [self.write(v, f"{where}[{i}]", depth + 1) for i, v in enumerate(items)]
        self.in_progress.discard(id(value))
        return {"$tuple" if type(value) is tuple else "$frozenset": written}

    def enum(self, value: enum.Enum, where: str, depth: int) -> dict:
        name = tag(type(value))
        if self.codec.classes.get(name) is not type(value):
            raise CheckpointError(f"{where}: enumeration {name} is not registered")
        return {"$enum": name, "value": self.write(value.value, where, depth + 1)}

    def array(self, value: np.ndarray | np.generic, where: str) -> dict:
        _checked_dtype(value.dtype, where, CheckpointError)
        if type(value) is not np.ndarray and not isinstance(value, np.generic):
            raise CheckpointError(f"{where}: an array of type {type(value).__name__}")
        self.arrays.append(np.array(value))
        key = "$scalar" if isinstance(value, np.generic) else "$array"
        return {key: len(self.arrays) - 1}

    def generator(self, value: np.random.Generator, where: str) -> dict:
        bit_generator = value.bit_generator
        name = type(bit_generator).__name__
        if _BIT_GENERATORS.get(name) is not type(bit_generator):
            raise CheckpointError(f"{where}: bit generator {name} is not supported")
        return {"$generator": name, "state": self.write(bit_generator.state, where)}

    def object(self, value: Any, where: str, depth: int) -> dict:
        cls = type(value)
        name = tag(cls)
        if self.codec.classes.get(name) is not cls:
            raise CheckpointError(f"{where}: cannot write a {name} (not a registered class)")
        node = self.remember(value, {"$object": name})
        if isinstance(value, dict):
            node["items"] = self.pairs(value, where, depth)
        elif isinstance(value, list):
            node["list"] = [self.write(v, f"{where}[{i}]", depth + 1) for i, v in enumerate(value)]
        state = value.__getstate__()
        if type(state) is dict and _plain_keys(list(state.items())):
            attributes = {k: self.write(v, f"{where}.{k}", depth + 2) for k, v in state.items()}
            node["state"] = {"$dict": [[k, v] for k, v in attributes.items()]}
        elif state is not None:
            node["state"] = self.write(state, f"{where}.state", depth + 1)
        return node


def _ordered(items: set | frozenset) -> list:
    """The members of a set in a stable order where they can be sorted (files compare equal)."""
    try:
        return sorted(items)
    except TypeError:
        return list(items)


def _checked_dtype(dtype: np.dtype, where: str, error: type[Exception]) -> np.dtype:
    if dtype.kind not in _ARRAY_KINDS or dtype.fields is not None or dtype.subdtype is not None:
        raise error(f"{where}: arrays of dtype {dtype} are not allowed")
    return dtype


def simplified(node: Any) -> Any:
    """The written document with unshared lists and dicts as plain JSON arrays and objects."""
    if isinstance(node, list):
        return [simplified(item) for item in node]
    if not isinstance(node, dict):
        return node
    if "$id" not in node and "$list" in node:
        return simplified(node["$list"])
    if "$id" not in node and "$dict" in node and _plain_keys(node["$dict"]):
        return {key: simplified(value) for key, value in node["$dict"]}
    return {key: simplified(value) for key, value in node.items()}


def _plain_keys(pairs: list) -> bool:
    return all(isinstance(k, str) and not k.startswith("$") for k, _ in pairs)


# -- reading -------------------------------------------------------------------------


class Refused(Exception):
    """A rule of the format broken; the message says which."""


class StateReader:
    """Rebuilds a state from a document and its arrays, calling nothing the file names."""

    def __init__(self, codec: StateCodec, arrays: Callable[[int], np.ndarray]) -> None:
        self.codec = codec
        self.arrays = arrays
        self.memo: dict[int, Any] = {}

    def read(self, node: Any) -> Any:
        if isinstance(node, list):
            return [self.read(item) for item in node]
        if not isinstance(node, dict):
            if isinstance(node, float) and not math.isfinite(node):
                raise Refused("holds a non-finite number outside a $float")
            return node
        form = next((key for key in node if key.startswith("$") and key != "$id"), None)
        if form is None:
            return self.memorised(node, {}, lambda d: d.update(self.pairs(node.items())))
        if form not in _FORMS:
            raise Refused(f"holds an unknown form {form!r}")
        return getattr(self, _FORMS[form])(node)

    def memorised(self, node: dict, value: Any, fill: Callable[[Any], None] | None = None) -> Any:
        """``value``, remembered under the node's ``$id`` before ``fill`` adds its contents."""
        if "$id" in node:
            key = node["$id"]
            if type(key) is not int or key in self.memo:
                raise Refused(f"holds a bad or repeated $id {key!r}")
            self.memo[key] = value
        if fill is not None:
            fill(value)
        return value

    def pairs(self, items: Iterable) -> Iterator[tuple[Any, Any]]:
        for pair in items:
            if isinstance(pair, tuple):  # a plain JSON object's items
                key, value = pair
                if key == "$id":
                    continue
                yield key, self.read(value)
                continue
            if not (isinstance(pair, list) and len(pair) == 2):
                raise Refused("holds a dict entry that is not a key-value pair")
            key = self.read(pair[0])
            try:
                hash(key)
            except TypeError:
                raise Refused("holds an unhashable dict key") from None
            yield key, self.read(pair[1])

    def content(self, node: dict, key: str, kind: type = list) -> Any:
        value = node.get(key)
        if type(value) is not kind:
            raise Refused(f"holds a {next(iter(node))} without its {key!r}")
        return value

    def read_ref(self, node: dict) -> Any:
        key = node["$ref"]
        if type(key) is not int or key not in self.memo:
            raise Refused(f"refers to {key!r}, which is not defined before")
        return self.memo[key]

    def read_list(self, node: dict) -> list:
        items = self.content(node, "$list")
        return self.memorised(node, [], lambda value: value.extend(self.read(i) for i in items))

    def read_dict(self, node: dict) -> dict:
        items = self.content(node, "$dict")
        return self.memorised(node, {}, lambda value: value.update(self.pairs(items)))

    def read_defaultdict(self, node: dict) -> defaultdict:
        factory = node["$defaultdict"]
        if factory is not None:
            factory = self.read_constant(factory) if isinstance(factory, dict) else None
            if factory is None or not isinstance(factory, type):
                raise Refused("holds a defaultdict whose factory is not a registered class")
        items = self.content(node, "items")
        value = defaultdict(factory)
        return self.memorised(node, value, lambda d: dict.update(d, self.pairs(items)))

    def read_set(self, node: dict) -> set:
        items = self.content(node, "$set")
        return self.memorised(node, set(), lambda value: value.update(self.hashables(items)))

    def hashables(self, items: list) -> list:
        values = [self.read(item) for item in items]
        try:
            hash(tuple(values))
        except TypeError:
            raise Refused("holds an unhashable member of a set") from None
        return values

    def read_tuple(self, node: dict) -> tuple:
        return self.memorised(node, tuple(self.read(i) for i in self.content(node, "$tuple")))

    def read_frozenset(self, node: dict) -> frozenset:
        items = self.content(node, "$frozenset")
        return self.memorised(node, frozenset(self.hashables(items)))

    def read_float(self, node: dict) -> float:
        text = node["$float"]
        if text not in ("nan", "inf", "-inf"):
            raise Refused(f"holds a $float {text!r}")
        return float(text)

    def read_bytes(self, node: dict) -> bytes:
        try:
            return base64.b64decode(self.content(node, "$bytes", str), validate=True)
        except ValueError:
            raise Refused("holds $bytes that are not base64") from None

    def read_dtype(self, node: dict) -> np.dtype:
        text = self.content(node, "$dtype", str)
        try:
            dtype = np.dtype(text)
        except TypeError:
            raise Refused(f"holds the dtype {text!r}") from None
        return _checked_dtype(dtype, "the checkpoint", Refused)

    def read_array(self, node: dict) -> np.ndarray:
        return self.memorised(node, self.arrays(node["$array"]))

    def read_scalar(self, node: dict) -> np.generic:
        array = self.arrays(node["$scalar"])
        if array.ndim != 0:
            raise Refused("holds a scalar that is not a 0-d array")
        return self.memorised(node, array[()])

    def read_constant(self, node: dict) -> Any:
        name = node.get("$constant")
        current = current_tag(name) if isinstance(name, str) else None
        if current not in self.codec.constants:
            raise Refused(f"names {name!r}, which a checkpoint may not hold")
        return self.codec.constants[current]

    def registered(self, name: Any, enumeration: bool) -> type:
        cls = self.codec.classes.get(current_tag(name)) if isinstance(name, str) else None
        if cls is None or issubclass(cls, enum.Enum) != enumeration:
            kind = "enumeration" if enumeration else "class"
            raise Refused(f"names the {kind} {name!r}, which a checkpoint may not hold")
        return cls

    def read_enum(self, node: dict) -> enum.Enum:
        cls = self.registered(node["$enum"], enumeration=True)
        try:
            return cls(self.read(node.get("value")))  # a look-up of a member by value
        except (ValueError, TypeError):
            raise Refused(f"holds a value that is no member of {node['$enum']}") from None

    def read_generator(self, node: dict) -> np.random.Generator:
        cls = _BIT_GENERATORS.get(node["$generator"])
        if cls is None:
            raise Refused(f"names the bit generator {node['$generator']!r}")
        bit_generator = cls()
        try:
            bit_generator.state = self.read(node.get("state"))
        except (TypeError, ValueError, KeyError):
            raise Refused(f"holds a bad {node['$generator']} state") from None
        return self.memorised(node, np.random.Generator(bit_generator))

    def read_object(self, node: dict) -> Any:
        cls = self.registered(node["$object"], enumeration=False)
        value = cls.__new__(cls)
        self.memorised(node, value)
        if "items" in node:
            if not isinstance(value, dict):
                raise Refused(f"gives items to {node['$object']}, which is not a dict")
            dict.update(value, self.pairs(self.content(node, "items")))
        if "list" in node:
            if not isinstance(value, list):
                raise Refused(f"gives a list to {node['$object']}, which is not a list")
            list.extend(value, [self.read(item) for item in self.content(node, "list")])
        if "state" in node:
            _restore(value, self.read(node["state"]), node["$object"])
        return value


#: The tagged forms of a document and the method of :class:`_Reader` that reads each.
_FORMS = {
    f"${name}": f"read_{name}"
    for name in "ref list dict defaultdict set tuple frozenset float bytes dtype array scalar"
    " constant enum generator object".split()
}


def _restore(value: Any, state: Any, name: str) -> None:
    """Give ``value`` its saved attributes, as pickle's BUILD does."""
    setstate = getattr(type(value), "__setstate__", None)
    if setstate is not None:
        setstate(value, state)
        return
    slots = None
    if isinstance(state, tuple) and len(state) == 2:
        state, slots = state
    for attributes in (state, slots):
        if attributes is None:
            continue
        if not isinstance(attributes, dict) or not all(isinstance(k, str) for k in attributes):
            raise Refused(f"gives {name} attributes that are not a dict of names")
        for key, item in attributes.items():
            object.__setattr__(value, key, item)


class ArrayLookup:
    """The archive's array ``a<i>``, read once, of an allowed dtype.

    ``archive`` is an :class:`amaze.archives.NpzArchive`: each header is
    checked before the array is inflated, and arrays of Python objects are
    refused there.
    """

    def __init__(self, archive: Any, size: int) -> None:
        self.archive = archive
        self.size = size

    def __call__(self, index: Any) -> np.ndarray:
        if type(index) is not int or not 0 <= index < self.size:
            raise Refused(f"refers to the array {index!r}, which it does not hold")
        array = self.archive.read(f"a{index}")
        _checked_dtype(array.dtype, "the checkpoint", Refused)
        return array

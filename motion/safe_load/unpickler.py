"""A pickle reader that builds plain data and refuses everything else.

A pickle is a small program: ``GLOBAL`` names a function or class by module and name,
``REDUCE`` and ``NEWOBJ`` call it, ``BUILD`` hands an object its state. Python's own
unpickler imports whatever is named and calls it, which is how a file runs
``os.system``. :class:`DataUnpickler` looks every name up in a table of builders written
in this package (arrays from their bytes, dtypes, sets, ...; see :mod:`.data_types`) and
raises :class:`RefusedObject` for any other name before anything is called; only those
builders are ever called, and ``BUILD`` only sets the state of arrays, dtypes and the
placeholders of this module. What a load returns is checked to be plain data
(:func:`check_plain`).
"""

from __future__ import annotations

import pickle
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

ALLOWED = ("numpy arrays, dtypes and scalars, numbers, strings, bytes, None, lists, tuples, "
           "dicts, sets and OrderedDicts (and chumpy arrays, scipy sparse matrices, torch "
           "tensors and joblib's arrays, as arrays)")


class DataFileError(ValueError):
    """A data file is unreadable, or holds something other than plain data."""


class RefusedObject(DataFileError):
    """A pickle names a function or class that is not data; nothing of the file was run."""

    def __init__(self, source: str, name: str, hint: str = ""):
        self.source, self.name = source, name
        super().__init__(
            f"{source}: refused: the file asks to build or call {name}, which is not plain "
            f"data ({ALLOWED}); nothing in it was run{hint}. Import only files whose pickles "
            "hold data: save the arrays alone (e.g. numpy.savez) and import that file"
        )


@dataclass(frozen=True)
class Function:
    """A builder a pickle may call by ``name`` (``module.qualname`` as the file writes it)."""

    name: str
    call: Callable


@dataclass(frozen=True)
class Marker:
    """A name that only stands as an argument of a builder (``numpy.ndarray``, ``object``)."""

    name: str


@dataclass(frozen=True)
class Kind:
    """A class a pickle may make with ``NEWOBJ``: ``make()`` returns a :class:`Placeholder`
    whose ``BUILD`` state turns it into data."""

    name: str
    make: Callable[[], "Placeholder"]


class Placeholder:
    """What a pickled object of a known class stands in as until its ``BUILD`` state arrives.

    ``finish(state, unpickler)`` returns the data it stands for; every reference the
    pickle keeps to it (its memo entries) is then replaced by that data.
    """

    name = "object"

    def __init__(self):
        self.memo_keys: list = []

    def finish(self, state, unpickler: "DataUnpickler"):
        raise NotImplementedError


class _Memo(dict):
    """The unpickler's memo, remembering where placeholders are kept so that they can be
    replaced by their data."""

    def __setitem__(self, key, value):
        super().__setitem__(key, value)
        if isinstance(value, Placeholder):
            value.memo_keys.append(key)


class DataUnpickler(pickle._Unpickler):
    """Read one pickle from ``file`` with the builders of ``names`` only.

    ``source`` names the file in every error. ``persistent_load`` (ids of objects kept
    outside the pickle) is refused unless ``persistent`` is given: torch's storages use
    it (:mod:`.torch_data`). Python 2 strings are read as latin-1, as numpy's arrays of
    Python 2 pickles (the official SMPL files) need.
    """

    dispatch = dict(pickle._Unpickler.dispatch)

    def __init__(self, file, source: str, names: dict, persistent: Callable | None = None):
        super().__init__(file, encoding="latin1")
        self.memo = _Memo()
        self.stream, self.source, self.names = file, str(source), names
        self.persistent = persistent

    def nested(self) -> "DataUnpickler":
        """Return a new unpickler reading the next pickle of the same stream."""
        return DataUnpickler(self.stream, self.source, self.names)

    def find_class(self, module, name):
        found = self.names.get((module, name))
        if found is None:
            hint = ("; of chumpy only its plain Ch arrays are read" if module.startswith("chumpy")
                    else "")
            raise RefusedObject(self.source, f"{module}.{name}", hint)
        return found

    def persistent_load(self, pid):
        if self.persistent is None:
            raise DataFileError(f"{self.source}: the pickle refers to an object kept outside it "
                                "(a persistent id), which plain data never does")
        return self.persistent(pid)

    def refuse(self, what) -> DataFileError:
        kind = (what.name if isinstance(what, (Function, Marker, Kind, Placeholder))
                else f"{type(what).__module__}.{type(what).__qualname__}")
        return DataFileError(f"{self.source}: the pickle uses {kind} in a way plain data "
                             f"never does ({ALLOWED} only)")

    def call(self, function, args):
        """Return ``function(*args)`` if ``function`` is one of the builders."""
        if isinstance(function, Kind):
            return self.new(function, args)
        if not isinstance(function, Function) or not isinstance(args, tuple):
            raise self.refuse(function)
        try:
            return function.call(*args)
        except DataFileError as exc:
            raise self.named(exc) from None
        except (TypeError, ValueError, OverflowError, KeyError, IndexError) as exc:
            raise DataFileError(f"{self.source}: {function.name} with arguments it does not "
                                f"take ({exc})") from None

    def new(self, kind, args):
        """Return the placeholder of a known class (``NEWOBJ``, ``copyreg._reconstructor``)."""
        if not isinstance(kind, Kind) or not isinstance(args, tuple):
            raise self.refuse(kind)
        try:
            return kind.make()
        except DataFileError as exc:
            raise self.named(exc) from None

    def named(self, error: DataFileError) -> DataFileError:
        """Return ``error`` with this file's name in front, if it lacks it."""
        if str(error).startswith(self.source):
            return error
        if isinstance(error, RefusedObject):  # from a pickle inside this one (a torch storage)
            return RefusedObject(f"{self.source}, in {error.source}", error.name)
        return DataFileError(f"{self.source}: {error}")

    def load_reduce(self):
        args = self.stack.pop()
        self.stack[-1] = self.call(self.stack[-1], args)

    dispatch[pickle.REDUCE[0]] = load_reduce

    def load_newobj(self):
        args = self.stack.pop()
        self.stack[-1] = self.new(self.stack[-1], args)

    dispatch[pickle.NEWOBJ[0]] = load_newobj

    def load_newobj_ex(self):
        kwargs = self.stack.pop()
        args = self.stack.pop()
        if kwargs:
            raise self.refuse(self.stack[-1])
        self.stack[-1] = self.new(self.stack[-1], args)

    dispatch[pickle.NEWOBJ_EX[0]] = load_newobj_ex

    def _instantiate(self, klass, args):  # INST and OBJ, protocols 0 and 1
        self.append(self.call(klass, tuple(args)))

    def load_build(self):
        state = self.stack.pop()
        target = self.stack[-1]
        if isinstance(target, Placeholder):
            value = target.finish(state, self)
            for key in target.memo_keys:
                dict.__setitem__(self.memo, key, value)
            self.stack[-1] = value
        elif type(target) is np.ndarray or isinstance(target, np.dtype):
            try:
                target.__setstate__(state)
            except (TypeError, ValueError) as exc:
                raise DataFileError(f"{self.source}: a numpy {type(target).__name__} with a "
                                    f"state it does not take ({exc})") from None
        else:
            raise self.refuse(target)

    dispatch[pickle.BUILD[0]] = load_build


def unpickle(file, source: str, names: dict, persistent: Callable | None = None):
    """Return the plain data of the pickle at the start of ``file`` (see the module doc)."""
    try:
        value = DataUnpickler(file, source, names, persistent).load()
    except DataFileError:
        raise
    except Exception as exc:  # a damaged pickle raises many types (EOFError, struct.error, ...)
        raise DataFileError(f"{source} is not a readable pickle of data "
                            f"({type(exc).__name__}: {exc})") from None
    check_plain(value, source)
    return value


LEAVES = (type(None), bool, int, float, complex, str, bytes, bytearray, np.generic, np.dtype)


def check_plain(root, source: str) -> None:
    """Raise :class:`DataFileError` unless ``root`` is made of plain data only.

    Containers are walked once each (a list may hold itself); object arrays are walked
    through their elements; scipy sparse matrices count as data.
    """
    stack, seen = [root], set()
    while stack:
        value = stack.pop()
        if isinstance(value, LEAVES):
            continue
        if isinstance(value, (np.ndarray, list, tuple, set, frozenset, dict)):
            if id(value) in seen:
                continue
            seen.add(id(value))
            if isinstance(value, np.ndarray):
                if value.dtype.hasobject:
                    stack.append(value.tolist())
            elif isinstance(value, dict):
                stack.extend(value.keys())
                stack.extend(value.values())
            else:
                stack.extend(value)
            continue
        if type(value).__module__.startswith("scipy.sparse"):
            continue
        name = getattr(value, "name", None) if isinstance(value, (Function, Marker, Kind,
                                                                  Placeholder)) else None
        raise DataFileError(f"{source}: holds {name or type(value).__qualname__}, which is not "
                            f"plain data ({ALLOWED})")

"""The one name → thing registry every registry of the project is made of.

Methods, datasets, formats, skeletons, rendering styles, study types and their analyses,
crowd platforms, background jobs, bot policies and metric protocols are each one
:class:`Registry`. The same rules hold for all of them:

- a name is registered once; a second registration under it is refused;
- ``get(name)`` returns exactly what was registered (a class stays a class, an object an
  object), and an unknown name raises ``KeyError`` listing the known ones;
- discovery has one rule: a registry made with ``package=`` imports every module of that
  package whose name does not start with ``_`` before its first lookup, so a new plug-in
  is a module in that folder and no list names it.

Plain Python only (no third-party import): every layer can use it.
"""

from __future__ import annotations

import importlib
import pkgutil
import threading
from collections.abc import Iterator


class Registry:
    """Map snake_case names to registered classes or objects."""

    def __init__(self, kind: str, package: str | None = None):
        self.kind = kind
        self.package = package
        self._items: dict[str, object] = {}
        self._discovered = package is None
        self._done = package is None  # discovered, and every import finished
        self._lock = threading.RLock()

    def register(self, name: str):
        """Return a decorator adding a class (or function) under ``name``; a class gets
        ``name`` as its attribute."""

        def decorator(item):
            self.add(name, item)
            if isinstance(item, type):
                item.name = name
            return item

        return decorator

    def add(self, name: str, item):
        """Add ``item`` under ``name``; refuse a name already taken. Return ``item``."""
        if name in self._items:
            raise ValueError(f"{self.kind} {name!r} is already registered")
        self._items[name] = item
        return item

    def pop(self, name: str):
        """Remove ``name`` and return what was registered under it."""
        return self._items.pop(name)

    def get(self, name: str):
        """Return what was registered under ``name``."""
        self.discover()
        try:
            return self._items[name]
        except KeyError:
            raise KeyError(
                f"unknown {self.kind} {name!r}; choose one of: {', '.join(self.names())}"
            ) from None

    def names(self) -> list[str]:
        """Return the registered names, sorted."""
        self.discover()
        return sorted(self._items)

    def items(self) -> list[tuple[str, object]]:
        """Return ``(name, registered)`` pairs, sorted by name."""
        return [(name, self._items[name]) for name in self.names()]

    def discover(self) -> None:
        """Import every module of ``package`` not starting with ``_`` (once)."""
        if self._done:
            return
        # Another thread waits here until the imports are done (it would find the names
        # missing otherwise); the importing thread itself may look names up meanwhile.
        with self._lock:
            if self._discovered:
                return
            self._discovered = True  # before importing: a module may look names up
            try:
                package = importlib.import_module(self.package)
                for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
                    if not info.name.startswith("_"):
                        importlib.import_module(f"{self.package}.{info.name}")
            except BaseException:
                self._discovered = False
                raise
            self._done = True

    def __contains__(self, name: object) -> bool:
        self.discover()
        return name in self._items

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        self.discover()
        return len(self._items)

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {len(self._items)} registered)"

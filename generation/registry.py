"""A small name → class registry, shared by datasets and methods."""

from __future__ import annotations


class Registry:
    """Map snake_case keys to classes; ``register`` is a class decorator."""

    def __init__(self, kind: str):
        self.kind = kind
        self._items: dict[str, type] = {}

    def register(self, name: str):
        def decorator(cls):
            if name in self._items:
                raise ValueError(f"{self.kind} {name!r} is already registered")
            cls.name = name
            self._items[name] = cls
            return cls

        return decorator

    def get(self, name: str) -> type:
        try:
            return self._items[name]
        except KeyError:
            raise KeyError(
                f"unknown {self.kind} {name!r}; choose one of: {', '.join(self.names())}"
            ) from None

    def names(self) -> list[str]:
        return sorted(self._items)

"""Generative methods of motion, in one registry.

``get_method("a2m")`` returns a :class:`Method` subclass; build it from a config, a
skeleton, the action list, fps and clip length, then ``fit`` / ``sample`` / ``save``;
``load_checkpoint(path)`` rebuilds any saved method. The registry imports every module
of this package before its first lookup, so adding a method means adding one module
that calls ``@register_method("key")``.
"""

from __future__ import annotations

from pathlib import Path

from generation.methods.base import (
    METHODS,
    CheckpointError,
    Method,
    MethodConfig,
    MethodError,
    register_method,
)

def get_method(name: str) -> type[Method]:
    """Return the method class registered under ``name``."""
    return METHODS.get(name)


def list_methods() -> list[str]:
    """Return the keys of all registered methods."""
    return METHODS.names()


def load_checkpoint(path: str | Path, skeleton: str | None = None) -> Method:
    """Return the method saved at ``path``, whichever it is (see :meth:`Method.load`)."""
    return Method.load(path, skeleton=skeleton)


__all__ = [
    "CheckpointError", "Method", "MethodConfig", "MethodError", "get_method",
    "list_methods", "load_checkpoint", "register_method",
]

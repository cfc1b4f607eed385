"""Generative methods of motion, in one registry.

``get_method("a2m")`` returns a :class:`Method` subclass; build it from a config, a
skeleton, the action list, fps and clip length, then ``fit`` / ``sample`` / ``save``;
``load_checkpoint(path)`` rebuilds any saved method. Every module of this package that
is not a helper is imported here, so adding a method means adding one module that
calls ``@register_method("key")``.
"""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from generation.methods.base import (
    METHODS,
    CheckpointError,
    Method,
    MethodConfig,
    MethodError,
    register_method,
)

# Modules of this package that define no method.
HELPER_MODULES = {"base", "common", "kinematics", "training"}


def get_method(name: str) -> type[Method]:
    """Return the method class registered under ``name``."""
    return METHODS.get(name)


def list_methods() -> list[str]:
    """Return the keys of all registered methods."""
    return METHODS.names()


def load_checkpoint(path: str | Path, skeleton: str | None = None) -> Method:
    """Return the method saved at ``path``, whichever it is (see :meth:`Method.load`)."""
    return Method.load(path, skeleton=skeleton)


for _module in sorted(info.name for info in pkgutil.iter_modules(__path__)):
    if _module not in HELPER_MODULES and not _module.startswith("_"):
        importlib.import_module(f"{__name__}.{_module}")

__all__ = [
    "CheckpointError", "Method", "MethodConfig", "MethodError", "get_method",
    "list_methods", "load_checkpoint", "register_method",
]

"""What a format's detector may look at in one file, read once and only as data.

Every format module has ``detect(probe) -> str | None``: the reason it recognises the
file (``"an .npz with poses (T, 165): SMPL-X"``), or ``None``. Detectors look at the
probe's ``suffix``, ``keys`` (an ``.npz``'s member names, a dict's keys), ``shape`` (an
``.npy``'s or a member's), ``content`` (what an ``.npy`` of objects, a pickle or a joblib
file holds, read by :mod:`motion.safe_load`) and ``options`` (what the user passed,
e.g. ``classes_path``); each is read on first use and kept. A file that cannot be read as
data raises :class:`FormatError` (a refused pickle names what it asked for).
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path

import numpy as np

from motion import safe_load
from motion.formats.base import FormatError

PICKLES = (".pkl", ".pickle", ".joblib", ".pt", ".pth")
SUFFIXES = (".npy", ".npz", ".bvh") + PICKLES


class Probe:
    """One file, as its detectors see it."""

    def __init__(self, path: str | Path, options: dict | None = None):
        self.path = Path(path)
        self.suffix = self.path.suffix.lower()
        self.options = dict(options or {})
        self._members: dict[str, object] = {}

    def _read(self, read, *args):
        try:
            return read(*args)
        except safe_load.RefusedObject as exc:
            raise FormatError(str(exc)) from None
        except safe_load.DataFileError as exc:
            raise FormatError(f"{exc}; cannot tell its format") from None

    @cached_property
    def header(self) -> tuple[tuple[int, ...], np.dtype] | None:
        """An ``.npy``'s shape and dtype (``None`` for other files)."""
        return self._read(safe_load.npy_header, self.path) if self.suffix == ".npy" else None

    @property
    def shape(self) -> tuple[int, ...] | None:
        """An ``.npy`` array's shape (``None`` for other files and arrays of objects)."""
        header = self.header
        return tuple(header[0]) if header and not header[1].hasobject else None

    @cached_property
    def content(self):
        """What the file holds when it is not a plain array: a dict of an ``.npy`` of
        objects (unwrapped from its 0-d array), of a pickle or joblib file; ``None`` else."""
        if self.suffix == ".npy":
            if not self.header[1].hasobject:
                return None
            value = self._read(safe_load.load_npy, self.path)
            return value.item() if value.shape == () else value
        if self.suffix in PICKLES:
            return self._read(safe_load.load_data, self.path)
        return None

    @cached_property
    def keys(self) -> frozenset[str]:
        """An ``.npz``'s member names, or the keys of a dict the file holds."""
        if self.suffix == ".npz":
            return frozenset(self._read(safe_load.npz_names, self.path))
        content = self.content
        if isinstance(content, dict):
            return frozenset(str(key) for key in content)
        return frozenset()

    def member(self, name: str):
        """Return an ``.npz`` member (or a key of the dict the file holds), else ``None``."""
        if self.suffix == ".npz":
            if name not in self.keys:
                return None
            if name not in self._members:
                value = self._read(safe_load.load_npz, self.path, [name])[name]
                if isinstance(value, np.ndarray) and value.dtype == object and value.shape == ():
                    value = value.item()
                self._members[name] = value
            return self._members[name]
        content = self.content
        return content.get(name) if isinstance(content, dict) else None

    def member_shape(self, name: str) -> tuple[int, ...] | None:
        """Return the shape of a member that is an array, else ``None``."""
        value = self.member(name)
        shape = getattr(value, "shape", None)
        return tuple(shape) if shape is not None else None

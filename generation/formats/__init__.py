"""Motion file formats, one module each with ``load``; :func:`load_motions` reads any.

- ``npz``: the interchange file (README, "Interchange format"); option ``skeleton``
  (checked against the file's);
- ``a2m``: Action2Motion's joints and class-index ``.npy``; options ``classes_path``
  (required), ``skeleton``, ``file_fps`` (the arrays' frame rate), ``action_names``;
- ``bvh``: one BVH file, one motion; options ``skeleton`` and ``action`` (required),
  ``mapping``, ``scale``, ``up``.
"""

from __future__ import annotations

import inspect
from pathlib import Path

from generation import ops
from generation.formats import a2m, bvh, npz
from generation.formats.npz import FormatError
from generation.motion import Motion


def _load_npz(path, skeleton: str | None = None) -> list[Motion]:
    motions = npz.load(path)
    if skeleton and motions and motions[0].skeleton != skeleton:
        raise FormatError(f"{path} holds {motions[0].skeleton} motions, not {skeleton}")
    return motions


def _load_a2m(path, classes_path=None, skeleton: str | None = None,
              file_fps: float | None = None, action_names=None) -> list[Motion]:
    if classes_path is None:
        raise FormatError(f"{path}: Action2Motion joints need their class indices; pass "
                          "classes_path, a .npy of shape (N,)")
    return a2m.load(path, classes_path, skeleton, file_fps, action_names)


def _load_bvh(path, skeleton: str | None = None, action: str | None = None, mapping=None,
              scale="auto", up: str = "y") -> list[Motion]:
    if not skeleton or not action:
        raise FormatError(f"{path}: a BVH file needs skeleton (the project skeleton to map "
                          "it onto, e.g. h36m17 or humanact12) and action")
    try:
        return [bvh.to_skeleton(bvh.load(path, scale, up), skeleton, mapping, action)]
    except KeyError as exc:  # an unknown skeleton name
        raise FormatError(exc.args[0]) from None


LOADERS = {"npz": _load_npz, "a2m": _load_a2m, "bvh": _load_bvh}


def list_formats() -> list[str]:
    """Return the names of the formats :func:`load_motions` reads."""
    return sorted(LOADERS)


def load_motions(path: str | Path, format: str, fps: float | None = None,
                 source: str | None = None, **options) -> list[Motion]:
    """Read the motions of a file of any format; ``fps`` resamples, ``source`` relabels.

    ``options`` go to the format (see the module docstring).
    """
    try:
        loader = LOADERS[format]
    except KeyError:
        raise FormatError(f"unknown motion format {format!r}; formats: "
                          f"{', '.join(list_formats())}") from None
    accepted = list(inspect.signature(loader).parameters)[1:]
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        raise FormatError(f"format {format!r} takes options {', '.join(accepted)}; "
                          f"got {', '.join(unknown)}")
    motions = loader(path, **options)
    if fps:
        motions = [ops.resample(m, fps) for m in motions]
    if source:
        motions = [m.with_joints(m.joints, source=source, meta=dict(m.meta)) for m in motions]
    return motions


__all__ = ["FormatError", "LOADERS", "list_formats", "load_motions", "a2m", "bvh", "npz"]

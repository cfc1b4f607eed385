"""Detect the format of a file or folder from its content, then read it with that format.

What is looked at, in order (the result's ``notes`` say what was found and why):

- a folder with ``new_joint_vecs/`` or ``new_joints/``: ``humanml3d_vec`` / ``humanml3d``;
- a folder: the format of its files, each detected alone (e.g. ``bvh``, ``joints``);
- ``.bvh``: ``bvh``;
- ``.npz`` with ``joints``, ``actions``, ``skeleton``: ``npz``; with ``arr_0`` holding
  ``prompt`` and ``motion``: ``motioncritic``; with ``poses`` and ``trans``: ``amass``;
- ``.npy`` holding a dict with ``vertices`` and ``faces``: ``mdm`` (a mesh file); with
  ``motion`` and ``text``: ``mdm`` (``results.npy``); an array of shape
  ``(S, A, V, 3, T)``: ``actor``; ``(T, 12 J - 1)``: ``humanml3d_vec``; ``(T, J, 3)`` or
  ``(1, T, J, 3)``: ``joints``; ``(N, T, J*3)`` with ``classes_path``: ``a2m``.

``options`` go to the detected format when it takes them; the others are ignored.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np

from generation import safe_load
from generation.formats.base import FormatError, MotionList, get_format, natural_key
from generation.motion import Motion


def detect(path: str | Path, classes_path=None) -> tuple[str, str]:
    """Return ``(format, why)`` for a file or folder, or raise :class:`FormatError`."""
    path = Path(path)
    if path.is_dir():
        for folder, fmt in (("new_joint_vecs", "humanml3d_vec"), ("new_joints", "humanml3d")):
            if (path / folder).is_dir():
                return fmt, f"a {folder}/ folder (HumanML3D's layout)"
        if path.name in ("new_joint_vecs", "new_joints"):
            return ("humanml3d_vec" if path.name == "new_joint_vecs" else "humanml3d",
                    f"a {path.name} folder (HumanML3D's layout)")
        files = sorted((f for f in path.rglob("*") if f.suffix.lower() in (".npy", ".npz", ".bvh")
                        and f.stem not in ("Mean", "Std")), key=natural_key)
        if not files:
            raise FormatError(f"{path}: no .npy, .npz or .bvh files to detect a format from")
        found = {}
        for file in files:
            try:
                found.setdefault(detect(file, classes_path)[0], file)
            except FormatError:
                continue
        if not found:
            raise FormatError(f"{path}: no file in a known format (looked at {len(files)})")
        fmt = max(found, key=lambda f: sum(1 for file in files if _same(file, found[f])))
        return fmt, f"its files look like {fmt} (e.g. {found[fmt].name})"
    if not path.is_file():
        raise FormatError(f"{path} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return "bvh", "a .bvh file"
    if suffix == ".npz":
        return _detect_npz(path)
    if suffix == ".npy":
        return _detect_npy(path, classes_path)
    raise FormatError(f"{path}: cannot tell the format of a {suffix or 'suffix-less'} file; "
                      "pass --format")


def _same(file: Path, example: Path) -> bool:
    return file.suffix.lower() == example.suffix.lower()


def _detect_npz(path: Path) -> tuple[str, str]:
    try:
        keys = set(safe_load.npz_names(path))
        data = safe_load.load_npz(path, only=["arr_0"]) if "arr_0" in keys else {}
    except safe_load.RefusedObject as exc:
        raise FormatError(str(exc)) from None
    except safe_load.DataFileError as exc:
        raise FormatError(f"{exc}; cannot tell its format") from None
    if {"joints", "actions", "skeleton"} <= keys:
        return "npz", "an .npz with joints, actions and skeleton (the interchange file)"
    if "arr_0" in keys:
        content = data["arr_0"]
        if isinstance(content, np.ndarray) and content.dtype == object and content.shape == ():
            content = content.item()
        if isinstance(content, dict) and {"prompt", "motion"} <= set(content):
            return "motioncritic", "an .npz whose arr_0 holds prompt and motion"
    if {"poses", "trans"} <= keys:
        return "amass", "an .npz with poses and trans (AMASS)"
    raise FormatError(f"{path}: an .npz with keys {', '.join(sorted(keys))}, which no format "
                      "has; pass --format")


def _detect_npy(path: Path, classes_path) -> tuple[str, str]:
    from generation.formats.humanml3d_vec import joints_of_features

    try:
        shape, dtype = safe_load.npy_header(path)
        if dtype.hasobject:
            value = safe_load.load_npy(path)
    except safe_load.RefusedObject as exc:
        raise FormatError(str(exc)) from None
    except safe_load.DataFileError as exc:
        raise FormatError(f"{exc}; cannot tell its format") from None
    if dtype.hasobject:
        content = value.item() if value.shape == () else value
        if isinstance(content, dict) and {"vertices", "faces"} <= set(content):
            return "mdm", "a dict with vertices and faces (MDM's *_smpl_params.npy)"
        if isinstance(content, dict) and "motion" in content:
            return "mdm", "a dict with motion and text (MDM's results.npy)"
        raise FormatError(f"{path}: holds a {type(content).__name__}, which no format has")
    if len(shape) == 5 and shape[3] == 3:
        return "actor", f"an array of shape {shape}: (samples, actions, vertices, 3, T)"
    if len(shape) == 2 and joints_of_features(shape[1]):
        return "humanml3d_vec", f"an array of shape {shape}: HumanML3D features (T, 12 J - 1)"
    if shape[-1:] == (3,) and (len(shape) == 3 or (len(shape) == 4 and shape[0] == 1)):
        return "joints", f"an array of shape {shape}: joint positions (T, J, 3)"
    if classes_path is not None and len(shape) in (3, 4):
        return "a2m", f"an array of shape {shape} with class indices: Action2Motion"
    raise FormatError(f"{path}: an array of shape {shape}, which no format has; pass --format")


def load(path: str | Path, **options) -> list[Motion]:
    """Detect the format (see the module docstring) and read the file or folder with it."""
    fmt, why = detect(path, options.get("classes_path"))
    module = get_format(fmt)
    accepted = set(inspect.signature(module.load).parameters)
    loaded = module.load(path, **{k: v for k, v in options.items() if k in accepted})
    result = MotionList(problems=getattr(loaded, "problems", ()),
                        notes=[f"{path}: detected format {fmt!r} ({why})"])
    result.extend(loaded)
    result.notes.extend(getattr(loaded, "notes", ()))
    return result

"""The interchange file for sets of motions from any method.

One ``.npz`` holds one source's motions of one skeleton:

- ``joints``: ``(N, T, J, D)`` float32 (motions shorter than ``T`` are zero-padded);
- ``actions``: ``(N,)`` str;
- ``skeleton``: str, a registered skeleton name (or a file's own, see below);
- ``fps``: float;
- ``source``: str (``"real"`` or a method key);
- ``lengths``: optional ``(N,)`` int, each motion's true number of frames;
- ``texts``: optional ``(N,)`` str, the prompt each motion was generated from (or a real
  clip's caption); ``""`` for a motion without one;
- ``vertices``: optional ``(N, T, V, 3)`` float32, the body surface of each motion when
  the import carried one, with ``faces``: ``(F, 3)`` int, its triangles (one topology
  for the whole file);
- ``joint_names``, ``parents``, ``sides`` (``(J,)`` str, int, str) and ``up``, ``units``
  (str): the hierarchy of a skeleton that came with a file (a BVH file's own), so that
  it travels with its motions; written only for such skeletons;
- ``modes``: optional ``(N,)`` int, the mode each motion was drawn from (``meta["mode"]``);
- ``end_targets``: optional ``(N, D)`` float, the root end point each motion was asked to
  reach, relative to its start (``meta["end"]``).

The optional per-motion arrays are written when every motion's ``meta`` has the key,
and read back into ``meta``; ODMO's metrics (mode homogeneity, dist_e) need them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.formats.base import (
    FormatError,
    MotionList,
    check_finite,
    files_in,
    format_module,
    read_npz,
)
from motion.motion import Motion, MotionError
from motion.skeletons import custom_skeleton, get_skeleton, is_custom, sides_of

REQUIRED = ("joints", "actions", "skeleton", "fps", "source")
# Optional per-motion arrays and the meta key each one holds.
PER_MOTION = {"modes": "mode", "end_targets": "end"}
HIERARCHY = ("joint_names", "parents", "sides", "up", "units")
LAYOUT = ("an interchange .npz: joints (N, T, J, D), actions (N,), skeleton, fps, source, "
          "optional lengths, texts, vertices and faces (see README, 'Interchange format')")

__all__ = ["FormatError", "load", "save"]


def save(path: str | Path, motions: list[Motion]) -> Path:
    """Write motions of one skeleton, fps and source to an interchange ``.npz``."""
    path = Path(path)
    if not motions:
        raise FormatError(f"no motions to write to {path}")
    first = motions[0]
    for motion in motions:
        if (motion.skeleton, motion.fps, motion.source) != (first.skeleton, first.fps, first.source):
            raise FormatError(
                "an interchange file holds one skeleton, fps and source; got "
                f"{motion.skeleton}/{motion.fps}/{motion.source} beside "
                f"{first.skeleton}/{first.fps}/{first.source}"
            )
    lengths = np.array([m.frames for m in motions], dtype=np.int64)
    joints = np.zeros((len(motions), lengths.max()) + first.joints.shape[1:], np.float32)
    for i, motion in enumerate(motions):
        joints[i, : motion.frames] = motion.joints
    arrays = {
        "joints": joints,
        "actions": np.array([m.action for m in motions], dtype=str),
        "skeleton": np.array(first.skeleton),
        "fps": np.array(float(first.fps)),
        "source": np.array(first.source),
        "lengths": lengths,
        **_per_motion(motions),
        **_texts(motions),
        **_bodies(motions, lengths),
        **_hierarchy(first.skeleton),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as handle:
        np.savez_compressed(handle, **arrays)
    return path


def _texts(motions: list[Motion]) -> dict[str, np.ndarray]:
    if all(m.text is None for m in motions):
        return {}
    return {"texts": np.array([m.text or "" for m in motions], dtype=str)}


def _bodies(motions: list[Motion], lengths: np.ndarray) -> dict[str, np.ndarray]:
    """Return ``vertices`` and ``faces`` when the motions carry bodies of one topology."""
    bodies = [m for m in motions if m.has_body]
    if not bodies:
        return {}
    faces, count = bodies[0].faces, bodies[0].vertices.shape[1]
    if len(bodies) != len(motions) or any(
            m.vertices.shape[1] != count or m.faces.shape != faces.shape
            or not np.array_equal(m.faces, faces) for m in bodies):
        raise FormatError(
            f"{len(bodies)} of {len(motions)} motions carry a body surface, or their bodies "
            "differ in topology; an interchange file holds one topology for all its motions "
            "or none (import_motions --joints-only drops the surfaces)"
        )
    vertices = np.zeros((len(motions), lengths.max(), count, 3), np.float32)
    for i, motion in enumerate(motions):
        vertices[i, : motion.frames] = motion.vertices
    return {"vertices": vertices, "faces": faces.astype(np.int64)}


def _hierarchy(name: str) -> dict[str, np.ndarray]:
    """Return the arrays that carry a file's own skeleton (nothing for built-in ones)."""
    if not is_custom(name):
        return {}
    skeleton = get_skeleton(name)
    return {
        "joint_names": np.array(skeleton.joint_names, dtype=str),
        "parents": np.array(skeleton.parents, dtype=np.int64),
        "sides": np.array(sides_of(skeleton), dtype=str),
        "up": np.array(skeleton.up),
        "units": np.array(skeleton.units),
    }


def _per_motion(motions: list[Motion]) -> dict[str, np.ndarray]:
    """Return the optional arrays whose meta key every motion has (see :data:`PER_MOTION`)."""
    arrays = {}
    if all("mode" in m.meta for m in motions):
        arrays["modes"] = np.array([int(m.meta["mode"]) for m in motions], dtype=np.int64)
    if all("end" in m.meta for m in motions):
        ends = [np.asarray(m.meta["end"], dtype=np.float64) for m in motions]
        dims = motions[0].joints.shape[-1]
        wrong = [i for i, end in enumerate(ends) if end.shape != (dims,)]
        if wrong:
            raise FormatError(
                f"motion {wrong[0]} has meta['end'] of shape {ends[wrong[0]].shape}; an end "
                f"target has one coordinate per joint axis ({dims})"
            )
        arrays["end_targets"] = np.stack(ends)
    return arrays


def load(path: str | Path, skeleton: str | None = None) -> list[Motion]:
    """Read an interchange ``.npz`` (or a folder of them) into motions.

    ``skeleton``, when given, is checked against the file's.
    """
    path = Path(path)
    if path.is_dir():
        result = MotionList()
        for file in files_in(path, ("*.npz",), "interchange .npz files"):
            result.absorb(load(file, skeleton))
        return result
    if not path.is_file():
        raise FormatError(f"motions file {path} does not exist")
    arrays = read_npz(path, "motions")
    missing = [key for key in REQUIRED if key not in arrays]
    if missing:
        raise FormatError(
            f"{path} lacks {', '.join(missing)}; an interchange file has "
            f"{', '.join(REQUIRED)} and optional lengths (see README, 'Interchange format')"
        )
    joints, actions = arrays["joints"], arrays["actions"]
    if joints.ndim != 4:
        raise FormatError(f"{path}: joints must be (N, T, J, D); got shape {joints.shape}")
    count, frames = joints.shape[:2]
    if actions.shape != (count,):
        raise FormatError(
            f"{path}: actions must be ({count},), one per motion; got {actions.shape}"
        )
    name = _skeleton(arrays, path)
    if skeleton and name != skeleton:
        raise FormatError(f"{path} holds {name} motions, not {skeleton}")
    lengths = arrays.get("lengths", np.full(count, frames))
    if lengths.shape != (count,) or (lengths < 1).any() or (lengths > frames).any():
        raise FormatError(f"{path}: lengths must be (N,) in 1..{frames}")
    texts = _read_texts(arrays, count, path)
    vertices, faces = _read_bodies(arrays, count, frames, path)
    fps, source = float(arrays["fps"]), str(arrays["source"])
    metas = [{} for _ in range(count)]
    for key_name, key in PER_MOTION.items():
        if key_name in arrays:
            values = arrays[key_name]
            if len(values) != count:
                raise FormatError(f"{path}: {key_name} has {len(values)} rows for {count} motions")
            for meta, value in zip(metas, values):
                meta[key] = int(value) if key_name == "modes" else value
    try:
        return [
            Motion(joints[i, : int(lengths[i])], name, fps, str(actions[i]), source,
                   meta=metas[i], text=texts[i],
                   vertices=None if vertices is None else vertices[i, : int(lengths[i])],
                   faces=faces)
            for i in range(count)
        ]
    except MotionError as exc:
        raise FormatError(f"{path}: {exc}") from None


def _skeleton(arrays: dict, path: Path) -> str:
    """Return the file's skeleton name, registering a hierarchy the file carries."""
    name = str(arrays["skeleton"])
    if all(key in arrays for key in HIERARCHY):
        try:
            custom = custom_skeleton(arrays["joint_names"].tolist(), arrays["parents"].tolist(),
                                     str(arrays["up"]), str(arrays["units"]),
                                     prefix=name.rsplit("_", 1)[0],
                                     sides=arrays["sides"].tolist())
        except ValueError as exc:
            raise FormatError(f"{path}: the skeleton hierarchy it carries is invalid ({exc})") \
                from None
        if custom.name != name:
            raise FormatError(f"{path}: skeleton {name!r} does not match the hierarchy the "
                              f"file carries (it hashes to {custom.name!r})")
        return name
    try:
        get_skeleton(name)
    except KeyError as exc:
        raise FormatError(f"{path}: {exc.args[0]}") from None
    return name


def _read_texts(arrays: dict, count: int, path: Path) -> list[str | None]:
    if "texts" not in arrays:
        return [None] * count
    texts = arrays["texts"]
    if texts.shape != (count,):
        raise FormatError(f"{path}: texts has shape {texts.shape}; expected ({count},), one "
                          "prompt per motion ('' for none)")
    return [str(t) or None for t in texts]


def _read_bodies(arrays: dict, count: int, frames: int, path: Path):
    if "vertices" not in arrays and "faces" not in arrays:
        return None, None
    if "vertices" not in arrays or "faces" not in arrays:
        raise FormatError(f"{path}: vertices and faces come together; the file has only one")
    vertices, faces = arrays["vertices"], arrays["faces"]
    if vertices.ndim != 4 or vertices.shape[:2] != (count, frames) or vertices.shape[3] != 3:
        raise FormatError(f"{path}: vertices has shape {vertices.shape}; expected "
                          f"({count}, {frames}, V, 3)")
    check_finite(vertices, path, "vertices")
    return vertices, faces


def detect(probe) -> str | None:
    """Recognise the interchange file by its members."""
    if probe.suffix == ".npz" and {"joints", "actions", "skeleton"} <= probe.keys:
        return "an .npz with joints, actions and skeleton (the interchange file)"
    return None


format_module(__name__)

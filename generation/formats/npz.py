"""The interchange file for sets of motions from any method.

One ``.npz`` holds one source's motions of one skeleton:

- ``joints``: ``(N, T, J, D)`` float32 (motions shorter than ``T`` are zero-padded);
- ``actions``: ``(N,)`` str;
- ``skeleton``: str, a registered skeleton name;
- ``fps``: float;
- ``source``: str (``"real"`` or a method key);
- ``lengths``: optional ``(N,)`` int, each motion's true number of frames;
- ``modes``: optional ``(N,)`` int, the mode each motion was drawn from (``meta["mode"]``);
- ``end_targets``: optional ``(N, D)`` float, the root end point each motion was asked to
  reach, relative to its start (``meta["end"]``).

The optional per-motion arrays are written when every motion's ``meta`` has the key,
and read back into ``meta``; ODMO's metrics (mode homogeneity, dist_e) need them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from generation.motion import Motion, MotionError
from generation.skeletons import get_skeleton

REQUIRED = ("joints", "actions", "skeleton", "fps", "source")
# Optional per-motion arrays and the meta key each one holds.
PER_MOTION = {"modes": "mode", "end_targets": "end"}


class FormatError(ValueError):
    """A motions file is missing, unreadable or not in the interchange layout."""


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
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as handle:
        np.savez_compressed(
            handle,
            joints=joints,
            actions=np.array([m.action for m in motions], dtype=str),
            skeleton=np.array(first.skeleton),
            fps=np.array(float(first.fps)),
            source=np.array(first.source),
            lengths=lengths,
            **_per_motion(motions),
        )
    return path


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


def load(path: str | Path) -> list[Motion]:
    """Read an interchange ``.npz`` into motions."""
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"motions file {path} does not exist")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
    except Exception as exc:  # numpy raises many types for a broken zip
        raise FormatError(f"{path} is not a readable .npz file ({exc})") from exc
    missing = [key for key in REQUIRED if key not in arrays]
    if missing:
        raise FormatError(
            f"{path} lacks {', '.join(missing)}; an interchange file has "
            f"{', '.join(REQUIRED)} and optional lengths (see README, 'Interchange format')"
        )
    joints, actions = arrays["joints"], arrays["actions"]
    if joints.ndim != 4:
        raise FormatError(f"{path}: joints must be (N, T, J, D); got shape {joints.shape}")
    if actions.shape != (joints.shape[0],):
        raise FormatError(
            f"{path}: actions must be ({joints.shape[0]},), one per motion; got {actions.shape}"
        )
    skeleton = str(arrays["skeleton"])
    try:
        get_skeleton(skeleton)
    except KeyError as exc:
        raise FormatError(f"{path}: {exc.args[0]}") from None
    lengths = arrays.get("lengths", np.full(joints.shape[0], joints.shape[1]))
    if lengths.shape != (joints.shape[0],) or (lengths < 1).any() or (lengths > joints.shape[1]).any():
        raise FormatError(f"{path}: lengths must be (N,) in 1..{joints.shape[1]}")
    fps, source = float(arrays["fps"]), str(arrays["source"])
    metas = [{} for _ in range(joints.shape[0])]
    for name, key in PER_MOTION.items():
        if name in arrays:
            values = arrays[name]
            if len(values) != len(metas):
                raise FormatError(f"{path}: {name} has {len(values)} rows for {len(metas)} motions")
            for meta, value in zip(metas, values):
                meta[key] = int(value) if name == "modes" else value
    try:
        return [
            Motion(joints[i, : int(lengths[i])], skeleton, fps, str(actions[i]), source, meta=metas[i])
            for i in range(joints.shape[0])
        ]
    except MotionError as exc:
        raise FormatError(f"{path}: {exc}") from None

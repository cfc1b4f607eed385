"""Action2Motion's sample files: joints ``(N, T, J*3)`` and class indices ``(N,)``.

Action2Motion (Guo et al. 2020, seed 000) writes generated motions as two ``.npy``
arrays: joint positions ``(N, T, J*3)`` (``x, y, z`` of joint 0, then joint 1, ...;
``(N, T, J, 3)`` is read too) and each motion's class index ``(N,)``, counting from 0.
Class ``k`` is named ``action_names[k]``; by default HumanAct12's 12 coarse classes for
the ``humanact12`` skeleton, else ``class<k>``. The skeleton is the only registered 3D
skeleton for ``J`` joints (24: ``humanact12``, 17: ``h36m17``) unless given. The files
hold no frame rate: ``file_fps`` defaults to the skeleton's dataset rate
(:data:`DEFAULT_FPS`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.datasets import humanact12
from motion.formats.base import FormatError, finite_only, format_module, read_npy, skeleton_for
from motion.motion import Motion

DEFAULT_ACTIONS = {"humanact12": humanact12.CLASSES}
DEFAULT_FPS = {"humanact12": humanact12.HumanAct12.fps, "h36m17": 25.0}
SKELETONS = {24: "humanact12", 17: "h36m17"}
SOURCE = "a2m"


def load(path: str | Path, classes_path: str | Path | None = None, skeleton: str | None = None,
         file_fps: float | None = None, action_names=None, source: str = SOURCE) -> list[Motion]:
    """Read Action2Motion samples into motions (see the module docstring)."""
    if classes_path is None:
        raise FormatError(f"{path}: Action2Motion joints need their class indices; pass "
                          "classes_path, a .npy of shape (N,)")
    path, classes_path = Path(path), Path(classes_path)
    joints = read_npy(path, "joints (N, T, J*3)")
    if joints.ndim == 4 and joints.shape[-1] == 3:
        joints = joints.reshape(joints.shape[:2] + (-1,))
    if joints.ndim != 3 or joints.shape[-1] % 3 or 0 in joints.shape:
        raise FormatError(
            f"{path}: joints of shape {joints.shape}; expected (N, T, J*3): N motions of T "
            "frames, x, y, z of J joints, e.g. (N, 60, 72) for humanact12's 24 joints"
        )
    count, frames, n_joints = joints.shape[0], joints.shape[1], joints.shape[2] // 3
    skeleton = skeleton_for(n_joints, skeleton, path, joints.shape, SKELETONS)
    classes = _classes(read_npy(classes_path, f"class indices ({count},)"), count, classes_path,
                       path)
    if action_names is None:
        names = DEFAULT_ACTIONS.get(skeleton) or [f"class{k}" for k in range(classes.max() + 1)]
    else:
        names = list(action_names)
    if classes.max() >= len(names):
        raise FormatError(
            f"{classes_path}: class index {int(classes.max())} but {len(names)} action names "
            f"({', '.join(names)}); pass action_names, one per class index from 0"
        )
    fps = file_fps or DEFAULT_FPS.get(skeleton)
    if not fps:
        raise FormatError(f"{path}: an Action2Motion file holds no frame rate and skeleton "
                          f"{skeleton!r} has no usual one; pass file_fps")
    joints = joints.reshape(count, frames, n_joints, 3)
    return finite_only([
        Motion(joints[i], skeleton, fps, names[k], source,
               meta={"file": str(path), "index": i, "class": int(k)})
        for i, k in enumerate(classes)
    ], path)


def _classes(classes: np.ndarray, count: int, classes_path: Path, path: Path) -> np.ndarray:
    """Return class indices ``(N,)`` as ints, checked against the joints' ``N``."""
    if classes.shape == (count, 1):
        classes = classes[:, 0]
    if classes.shape != (count,):
        raise FormatError(
            f"{classes_path}: class indices of shape {classes.shape}; expected ({count},), "
            f"one per motion of {path}"
        )
    if not np.issubdtype(classes.dtype, np.number) or (classes != np.round(classes)).any() \
            or (classes < 0).any():
        raise FormatError(f"{classes_path}: class indices must be whole numbers from 0; "
                          f"got {classes.dtype} values {classes[:5].tolist()}")
    return classes.astype(np.int64)


def detect(probe) -> str | None:
    """Recognise Action2Motion's joints ``.npy`` when its class indices are given."""
    shape = probe.shape
    if shape is not None and probe.options.get("classes_path") and len(shape) in (3, 4):
        return f"an array of shape {shape} with class indices: Action2Motion"
    return None


format_module(__name__)

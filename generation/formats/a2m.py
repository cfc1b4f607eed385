"""Action2Motion's sample files: joints ``(N, T, J*3)`` and class indices ``(N,)``.

Action2Motion (Guo et al. 2020, seed 000) writes generated motions as two ``.npy``
arrays: joint positions ``(N, T, J*3)`` (``x, y, z`` of joint 0, then joint 1, ...;
``(N, T, J, 3)`` is read too) and each motion's class index ``(N,)``, counting from 0.
Class ``k`` is named ``action_names[k]``; by default HumanAct12's 12 coarse classes for
the ``humanact12`` skeleton, else ``class<k>``. The skeleton is the only registered 3D
skeleton with ``J`` joints (24: ``humanact12``, 17: ``h36m17``) unless given. The files
hold no frame rate: ``fps`` defaults to the skeleton's dataset rate (:data:`DEFAULT_FPS`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from generation.datasets import humanact12
from generation.formats.npz import FormatError
from generation.motion import Motion
from generation.skeletons import get_skeleton, list_skeletons

DEFAULT_ACTIONS = {"humanact12": humanact12.CLASSES}
DEFAULT_FPS = {"humanact12": humanact12.HumanAct12.fps, "h36m17": 25.0}
SOURCE = "a2m"


def load(path: str | Path, classes_path: str | Path, skeleton: str | None = None,
         fps: float | None = None, action_names=None, source: str = SOURCE) -> list[Motion]:
    """Read Action2Motion samples into motions (see the module docstring)."""
    path, classes_path = Path(path), Path(classes_path)
    joints = _read(path, "joints (N, T, J*3)")
    if joints.ndim == 4 and joints.shape[-1] == 3:
        joints = joints.reshape(joints.shape[:2] + (-1,))
    if joints.ndim != 3 or joints.shape[-1] % 3 or 0 in joints.shape:
        raise FormatError(
            f"{path}: joints of shape {joints.shape}; expected (N, T, J*3): N motions of T "
            "frames, x, y, z of J joints, e.g. (N, 60, 72) for humanact12's 24 joints"
        )
    count, frames, n_joints = joints.shape[0], joints.shape[1], joints.shape[2] // 3
    skeleton = _skeleton(n_joints, skeleton, path, joints.shape)
    classes = _classes(_read(classes_path, f"class indices ({count},)"), count, classes_path, path)
    if action_names is None:
        names = DEFAULT_ACTIONS.get(skeleton) or [f"class{k}" for k in range(classes.max() + 1)]
    else:
        names = list(action_names)
    if classes.max() >= len(names):
        raise FormatError(
            f"{classes_path}: class index {int(classes.max())} but {len(names)} action names "
            f"({', '.join(names)}); pass action_names, one per class index from 0"
        )
    fps = fps or DEFAULT_FPS.get(skeleton)
    if not fps:
        raise FormatError(f"{path}: an Action2Motion file holds no frame rate and skeleton "
                          f"{skeleton!r} has no usual one; pass fps")
    joints = joints.reshape(count, frames, n_joints, 3)
    return [
        Motion(joints[i], skeleton, fps, names[k], source,
               meta={"file": str(path), "index": i, "class": int(k)})
        for i, k in enumerate(classes)
    ]


def _read(path: Path, what: str) -> np.ndarray:
    """Return the array of a .npy file, or raise FormatError naming the file."""
    if not path.is_file():
        raise FormatError(f"{path} does not exist; expected a .npy file of {what}")
    try:
        return np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for a damaged file
        raise FormatError(f"{path} is not a readable .npy file of {what} ({exc})") from exc


def _skeleton(n_joints: int, name: str | None, path: Path, shape) -> str:
    """Return the given skeleton, checked, or the one 3D skeleton with ``n_joints`` joints."""
    if name is not None:
        try:
            skeleton = get_skeleton(name)
        except KeyError as exc:
            raise FormatError(exc.args[0]) from None
        if skeleton.dims != 3 or skeleton.n_joints != n_joints:
            raise FormatError(
                f"{path}: joints of shape {shape} hold {n_joints} joints per frame; skeleton "
                f"{name!r} has {skeleton.n_joints} joints in {skeleton.dims}D"
            )
        return name
    fitting = [s for s in list_skeletons()
               if get_skeleton(s).dims == 3 and get_skeleton(s).n_joints == n_joints]
    if len(fitting) != 1:
        known = ", ".join(f"{s} ({get_skeleton(s).n_joints})" for s in list_skeletons()
                          if get_skeleton(s).dims == 3)
        raise FormatError(
            f"{path}: joints of shape {shape} hold {n_joints} joints per frame, which "
            f"{'several' if fitting else 'no'} 3D skeleton{'s' if fitting else ''} "
            f"{'have' if fitting else 'has'} (3D skeletons: {known}); pass skeleton"
        )
    return fitting[0]


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

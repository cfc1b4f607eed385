"""HumanML3D's feature vectors: ``new_joint_vecs/<id>.npy`` ``(T, 263)``, as joints.

Each frame is ``12 J - 1`` numbers (263 for HumanML3D's 22 joints, 251 for KIT-ML's 21):
the root's rotation velocity about y, its linear velocity in x and z, its height, then
the ``J - 1`` other joints' positions relative to the root without its rotation about y
(rotation-invariant), then rotations, velocities and foot contacts (not needed here).
The joints are recovered as the dataset's own ``recover_from_ric`` does: the root's
angle is the running sum of its rotation velocities (shifted by one frame), its
position the running sum of its velocities turned by that angle, its height read
directly; the other joints are turned back by the angle and moved by the root's x, z.

Model outputs are usually normalised: pass ``mean`` and ``std`` (``Mean.npy`` and
``Std.npy`` of ``(12 J - 1,)``) to de-normalise them first (``x * std + mean``); the
dataset's own files are not normalised. A file may hold one motion ``(T, D)`` or
several ``(N, T, D)``. Captions come from ``texts/`` as for ``humanml3d``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.formats.base import (
    FormatError,
    MotionList,
    check_finite,
    check_shape,
    format_module,
    load_each,
    read_npy,
    skeleton_for,
)
from motion.formats.humanml3d import SKELETONS, data_files, motion_of, texts_folder
from motion.motion import Motion

LAYOUT = ("HumanML3D's new_joint_vecs/<id>.npy of shape (T, 263) (KIT-ML: (T, 251)); "
          "features of 12 J - 1 numbers per frame")


def joints_of_features(count: int) -> int | None:
    """Return the number of joints of ``count`` features per frame (``12 J - 1``)."""
    return (count + 1) // 12 if count > 12 and (count + 1) % 12 == 0 else None


def qinv(q: np.ndarray) -> np.ndarray:
    """Return the inverse of unit quaternions ``(..., 4)`` (w, x, y, z)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Return vectors ``(..., 3)`` rotated by unit quaternions ``(..., 4)``."""
    axis = q[..., 1:]
    uv = np.cross(axis, v)
    uuv = np.cross(axis, uv)
    return v + 2.0 * (q[..., :1] * uv + uuv)


def recover_root(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the root's rotation quaternions ``(T, 4)`` and positions ``(T, 3)``."""
    velocity = features[:, 0]
    angle = np.zeros_like(velocity)
    angle[1:] = velocity[:-1]
    angle = np.cumsum(angle)
    quaternion = np.zeros((len(features), 4))
    quaternion[:, 0] = np.cos(angle)
    quaternion[:, 2] = np.sin(angle)
    position = np.zeros((len(features), 3))
    position[1:, [0, 2]] = features[:-1, 1:3]
    position = np.cumsum(qrot(qinv(quaternion), position), axis=0)
    position[:, 1] = features[:, 3]
    return quaternion, position


def recover_from_ric(features: np.ndarray, n_joints: int) -> np.ndarray:
    """Return joints ``(T, J, 3)`` of features ``(T, 12 J - 1)`` (see the module docstring)."""
    features = np.asarray(features, dtype=np.float64)
    quaternion, root = recover_root(features)
    local = features[:, 4:4 + (n_joints - 1) * 3].reshape(len(features), n_joints - 1, 3)
    turn = np.broadcast_to(qinv(quaternion)[:, None], local.shape[:-1] + (4,))
    positions = qrot(turn, local)
    positions[..., 0] += root[:, None, 0]
    positions[..., 2] += root[:, None, 2]
    return np.concatenate([root[:, None], positions], axis=1)


def _statistics(path, width: int, what: str) -> np.ndarray | None:
    if path is None:
        return None
    values = check_shape(read_npy(Path(path), f"{what} ({width},)").astype(np.float64),
                         lambda s: s == (width,), Path(path), what,
                         f"({width},), one per feature")
    check_finite(values, Path(path), what)
    return values


def load(path: str | Path, mean: str | Path | None = None, std: str | Path | None = None,
         skeleton: str | None = None, action: str | None = None, file_fps: float | None = None,
         source: str = "real") -> list[Motion]:
    """Read HumanML3D feature files as joints, de-normalised with ``mean``/``std`` if given."""
    if (mean is None) != (std is None):
        raise FormatError("pass both mean and std (Mean.npy and Std.npy), or neither")
    files = data_files(Path(path), "new_joint_vecs", LAYOUT)
    texts = texts_folder(files[0], "new_joint_vecs")

    def one(file: Path) -> MotionList:
        features = check_shape(read_npy(file, "features (T, 263)"),
                               lambda s: len(s) in (2, 3) and joints_of_features(s[-1])
                               and min(s) > 0, file, "features", LAYOUT)
        check_finite(features, file, "features")
        width = features.shape[-1]
        n_joints = joints_of_features(width)
        scale, shift = _statistics(std, width, "std"), _statistics(mean, width, "mean")
        batch = features.reshape((-1,) + features.shape[-2:])
        name = skeleton_for(n_joints, skeleton, file, (None, n_joints, 3), SKELETONS)
        motions = MotionList()
        for number, clip in enumerate(batch):
            if scale is not None:
                clip = clip * scale + shift
            joints = recover_from_ric(clip, n_joints)
            motion = motion_of(file, joints, name, texts, action, file_fps, source)
            if len(batch) > 1:
                motion.meta["index"] = number
            motions.append(motion)
        return motions

    return load_each(files, one, "HumanML3D feature file")


__all__ = ["load", "recover_from_ric", "recover_root"]


def detect(probe) -> str | None:
    """Recognise a ``new_joint_vecs`` folder, or an array of HumanML3D features."""
    if probe.path.is_dir():
        if probe.path.name == "new_joint_vecs" or (probe.path / "new_joint_vecs").is_dir():
            return "a new_joint_vecs/ folder (HumanML3D's layout)"
        return None
    shape = probe.shape
    if shape is not None and len(shape) == 2 and joints_of_features(shape[1]):
        return f"an array of shape {shape}: HumanML3D features (T, 12 J - 1)"
    return None


format_module(__name__)

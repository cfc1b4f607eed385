"""SMPL pose parameters as MDM, ACTOR and MotionCritic store them, turned into joints.

Their action models write ``(25, 6, T)`` per motion: rows 0-23 the 6D rotations of
SMPL's 24 joints (the root's first), row 24 the root translation in its first three
values. Like their ``rotation2xyz``, the body is posed with zero shape and translated
by ``translation - translation[first frame]``.

These models learnt HumanAct12 and UESTC in a camera's frame, y pointing down (ACTOR's
renderer turns its meshes 180 degrees about x before drawing); :func:`stand_upright`
turns such motions onto y up.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.body_models import load_body_model, matrix_to_axis_angle, rotation_6d_to_matrix
from motion.formats.base import FormatError

HEAD, ANKLES = 15, (7, 8)  # SMPL joint indices
TURN_X = np.diag([1.0, -1.0, -1.0]).astype(np.float32)  # 180 degrees about x


def rot6d_layout(path: Path, key: str) -> str:
    return f"{key} of shape (25, 6, T): 24 SMPL joint rotations in 6D and the root translation"


def pose_rot6d(motion: np.ndarray, body_models=None, path: Path = Path("?"), key="motion"):
    """Return SMPL joints ``(T, 24, 3)``, vertices ``(T, 6890, 3)`` and faces of a
    ``(25, 6, T)`` rot6d motion (see the module docstring)."""
    motion = np.asarray(motion, dtype=np.float64)
    if motion.ndim != 3 or motion.shape[:2] != (25, 6) or motion.shape[2] < 1:
        raise FormatError(f"{path}: {key} has shape {motion.shape}; expected "
                          f"{rot6d_layout(path, key)}")
    rotations = rotation_6d_to_matrix(motion[:24].transpose(2, 0, 1))  # (T, 24, 3, 3)
    axis_angle = matrix_to_axis_angle(rotations)
    translation = motion[24, :3].T
    translation = translation - translation[:1]
    model = load_body_model("smpl", "neutral", body_models)
    joints, vertices = model.forward(axis_angle[:, 0], axis_angle[:, 1:].reshape(len(axis_angle), -1),
                                     transl=translation)
    return joints, vertices, model.faces


def stand_upright(joints: np.ndarray, vertices: np.ndarray | None = None, head: int = HEAD,
                  ankles=ANKLES):
    """Return joints (and vertices) turned 180 degrees about x if the head is below the feet
    along y, and whether they were turned."""
    height = joints[:, head, 1] - joints[:, list(ankles), 1].mean(axis=1)
    if np.median(height) >= 0:
        return joints, vertices, False
    turned = joints @ TURN_X.T
    return turned, None if vertices is None else vertices @ TURN_X.T, True

"""IsaacGym AMP motions: poselib's ``SkeletonMotion`` saved as an ``.npy``, z up, 60 fps.

``SkeletonMotion.to_file`` writes an ``np.save`` of an OrderedDict: ``rotation``
``(T, J, 4)`` local joint rotations as quaternions ``(x, y, z, w)``,
``root_translation`` ``(T, 3)``, ``skeleton_tree`` (``node_names``, ``parent_indices``,
``local_translation`` ``(J, 3)``), ``is_local``, ``fps``; each array as ``{"arr":
array, "context": {"dtype": ...}}``. The AMP humanoid has 15 joints (pelvis, torso,
head, arms, hands, thighs, shins, feet), metres. Joint positions come from forward
kinematics over the tree; the motion is the file's own skeleton (z up; sides from the
``left_``/``right_`` names), needing no body model.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from motion.formats.base import (
    FormatError,
    MotionList,
    files_in,
    format_module,
    load_each,
    need_keys,
)
from motion.formats.smpl_estimates import array, read_data
from motion.motion import UNKNOWN_ACTION, Motion
from motion.skeletons import custom_skeleton

LAYOUT = ("an AMP poselib SkeletonMotion .npy: rotation (T, J, 4) xyzw, root_translation "
          "(T, 3), skeleton_tree {node_names, parent_indices, local_translation (J, 3)}, fps")
FPS = 60.0


def load(path: str | Path, action: str | None = None, source: str = "real") -> list:
    """Read AMP motion files (a file, or a folder of them)."""
    files = files_in(Path(path), ("*.npy",), LAYOUT)
    return load_each(files, lambda file: MotionList([_one(file, action, source)]),
                     "AMP motion file")


def _one(path: Path, action, source) -> Motion:
    data = read_data(path, LAYOUT)
    if not isinstance(data, dict):
        raise FormatError(f"{path}: holds {type(data).__name__}; expected {LAYOUT}")
    need_keys(data, ("rotation", "root_translation", "skeleton_tree"), path, LAYOUT)
    tree = data["skeleton_tree"]
    if not isinstance(tree, dict):
        raise FormatError(f"{path}: skeleton_tree holds {type(tree).__name__}; expected {LAYOUT}")
    need_keys(tree, ("node_names", "parent_indices", "local_translation"), path, LAYOUT)
    names = [str(name) for name in tree["node_names"]]
    count = len(names)
    parents = array(tree["parent_indices"], path, "skeleton_tree.parent_indices", f"({count},)",
                    lambda s: s == (count,)).astype(int)
    if parents[0] != -1 or any(not -1 <= p < j for j, p in enumerate(parents)):
        raise FormatError(f"{path}: skeleton_tree.parent_indices {parents.tolist()}; expected -1 "
                          "for the first joint and each parent before its child")
    offsets = array(tree["local_translation"], path, "skeleton_tree.local_translation",
                    f"({count}, 3)", lambda s: s == (count, 3))
    quaternions = array(data["rotation"], path, "rotation", f"(T, {count}, 4)",
                        lambda s: len(s) == 3 and s[1:] == (count, 4) and s[0] > 0)
    frames = len(quaternions)
    root = array(data["root_translation"], path, "root_translation", f"({frames}, 3)",
                 lambda s: s == (frames, 3))
    norms = np.linalg.norm(quaternions, axis=-1)
    if (norms < 1e-6).any():
        raise FormatError(f"{path}: rotation holds zero quaternions; expected unit (x, y, z, w)")
    local = Rotation.from_quat((quaternions / norms[..., None]).reshape(-1, 4)).as_matrix()
    local = local.reshape(frames, count, 3, 3)
    world = np.empty_like(local)
    positions = np.empty((frames, count, 3))
    for joint, parent in enumerate(parents):
        if parent < 0:
            world[:, joint], positions[:, joint] = local[:, joint], root
        else:
            world[:, joint] = world[:, parent] @ local[:, joint]
            positions[:, joint] = positions[:, parent] + world[:, parent] @ offsets[joint]
    skeleton = custom_skeleton(names, parents.tolist(), up="z", units="m", prefix="amp",
                               description=f"the skeleton tree of {path.name}")
    fps = float(np.asarray(data.get("fps", FPS)).reshape(-1)[0])
    return Motion(positions.astype(np.float32), skeleton.name, fps, action or UNKNOWN_ACTION,
                  source, meta={"file": str(path)})


def detect(probe) -> str | None:
    """Recognise a poselib SkeletonMotion by its keys."""
    if probe.suffix == ".npy" and {"rotation", "root_translation", "skeleton_tree"} <= probe.keys:
        return "a SkeletonMotion dict (rotation, root_translation, skeleton_tree): AMP poselib"
    return None


format_module(__name__)

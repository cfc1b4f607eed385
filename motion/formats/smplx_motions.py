"""SMPL-X motions (BEAT2/EMAGE, AMASS's SMPL-X release, Motion-X), posed with smplx.

Three layouts of SMPL-X's 165 pose values (root 3, body 63, jaw 3, eyes 3 + 3, left and
right hand 45 each, axis-angle):

- BEAT2 / EMAGE ``.npz``: ``poses`` ``(T, 165)``, ``trans`` ``(T, 3)``, ``betas``
  (300), ``expressions`` ``(T, 100)``, ``mocap_frame_rate`` (30);
- AMASS's SMPL-X release ``.npz``: ``surface_model_type`` ``smplx``, ``poses``
  ``(T, 165)``, ``trans``, ``betas`` (16), ``gender``, ``mocap_frame_rate``; z up;
- Motion-X ``.npy`` ``(T, 322)``: ``root_orient`` 3, ``pose_body`` 63, ``pose_hand`` 90,
  ``pose_jaw`` 3, ``face_expr`` 50, ``face_shape`` 100, ``trans`` 3, ``betas`` 10; no
  frame rate (``file_fps``, default 30).

The joints come from the user's SMPL-X model (``DIR/smplx/SMPLX_NEUTRAL.npz``; see
:mod:`motion.body_models`): the 22 body joints as ``smpl22``, or with ``hands`` the
30 finger joints too (a skeleton of 52 joints of its own). The up axis is found from the
body (the one along which the head stands highest above the feet: AMASS is z up) and
turned onto y; a body whose lowest joint is more than 0.1 m off the floor is put on it
(``meta["placed"]`` says so). The surface is kept unless ``vertices`` is false.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.body_models import BodyModelError, load_body_model
from motion.formats.base import (
    FormatError,
    MotionList,
    files_in,
    format_module,
    load_each,
    need_keys,
    read_npz,
)
from motion.formats.smpl_estimates import array, read_data
from motion.motion import UNKNOWN_ACTION, Motion
from motion.ops import axis_rotation
from motion.skeletons import SMPL_JOINTS, SMPL_PARENTS, custom_skeleton

LAYOUT = ("SMPL-X poses: an .npz with poses (T, 165), trans (T, 3), betas, mocap_frame_rate "
          "(BEAT2/EMAGE, AMASS SMPL-X), or a Motion-X .npy (T, 322)")
WIDTH, MOTION_X = 165, 322
FPS = 30.0
CHUNK = 128
HEAD, ANKLES = 15, (7, 8)
FLOOR_TOLERANCE = 0.1
FINGERS = [f"{side}_{finger}{k}" for side in ("left", "right")
           for finger in ("index", "middle", "pinky", "ring", "thumb") for k in (1, 2, 3)]
HAND_PARENTS = [parent for wrist in (20, 21) for finger in range(5)
                for parent in (wrist, 22 + (wrist - 20) * 15 + finger * 3,
                               23 + (wrist - 20) * 15 + finger * 3)]


def hands_skeleton() -> str:
    """Return the skeleton of SMPL-X's 22 body joints and 30 finger joints."""
    return custom_skeleton(list(SMPL_JOINTS[:22]) + FINGERS, list(SMPL_PARENTS[:22]) +
                           HAND_PARENTS, up="y", units="m", prefix="smplx",
                           description="SMPL-X's 22 body joints and 30 finger joints").name


def load(path: str | Path, body_models: str | Path | None = None, gender: str | None = None,
         hands: bool = False, file_fps: float | None = None, action: str | None = None,
         vertices: bool = True, source: str = "real") -> list[Motion]:
    """Read SMPL-X files (a file, or a folder of them) through the user's SMPL-X model."""
    files = files_in(Path(path), ("*.npz", "*.npy"), LAYOUT)
    return load_each(files, lambda file: MotionList([_one(file, body_models, gender, hands,
                                                          file_fps, action, vertices, source)]),
                     "SMPL-X file")


def _parameters(path: Path, file_fps):
    """Return poses (T, 165), trans, betas, expressions, fps, gender and the layout's name."""
    if path.suffix.lower() == ".npy":
        values = array(read_data(path, LAYOUT), path, "motion", f"(T, {MOTION_X}) (Motion-X)",
                       lambda s: len(s) == 2 and s[1] == MOTION_X and s[0] > 0)
        root, body, hand, jaw = values[:, :3], values[:, 3:66], values[:, 66:156], \
            values[:, 156:159]
        poses = np.concatenate([root, body, jaw, np.zeros((len(values), 6)), hand], axis=1)
        return (poses, values[:, 309:312], values[0, 312:322], values[:, 159:209],
                file_fps or FPS, None, "Motion-X")
    data = read_npz(path, "SMPL-X pose parameters", objects=True)
    need_keys(data, ("poses",), path, LAYOUT)
    poses = array(data["poses"], path, "poses", f"(T, {WIDTH}) (SMPL-X)",
                  lambda s: len(s) == 2 and s[1] == WIDTH and s[0] > 0)
    frames = len(poses)
    trans = array(data["trans"], path, "trans", f"({frames}, 3)", lambda s: s == (frames, 3)) \
        if "trans" in data else None
    rate = data.get("mocap_frame_rate", data.get("mocap_framerate"))
    fps = float(np.asarray(rate).reshape(-1)[0]) if rate is not None else (file_fps or FPS)
    gender = data.get("gender")
    gender = None if gender is None else str(np.asarray(gender).item()).strip().lower() or None
    layout = "AMASS SMPL-X" if "surface_model_type" in data else "BEAT2/EMAGE"
    return poses, trans, data.get("betas"), data.get("expressions"), fps, gender, layout


def _one(path, body_models, gender, hands, file_fps, action, with_vertices, source) -> Motion:
    poses, trans, betas, expressions, fps, file_gender, layout = _parameters(path, file_fps)
    sex = gender or (file_gender if file_gender in ("male", "female") else "neutral")
    try:
        model = load_body_model("smplx", sex, body_models)
    except BodyModelError as exc:
        raise FormatError(f"{path}: {exc}") from None
    joints, surface = [], []
    for start in range(0, len(poses), CHUNK):
        part = slice(start, start + CHUNK)
        posed = model.forward(poses[part], None if trans is None else trans[part], betas,
                              None if expressions is None else np.asarray(expressions)[part],
                              hands=hands)
        joints.append(posed[0])
        if with_vertices:
            surface.append(posed[1])
    joints = np.concatenate(joints)
    surface = np.concatenate(surface) if with_vertices else None
    turn = _up_turn(joints)
    joints = joints @ turn.T
    surface = None if surface is None else surface @ turn.T
    meta = {"file": str(path), "layout": layout, "gender": sex, "body_model": str(model.path),
            "up": _axis_name(turn)}
    lowest = float(np.median(joints[..., 1].min(axis=1)))
    if abs(lowest) > FLOOR_TOLERANCE:
        shift = np.array([0, lowest, 0], np.float32)
        joints, surface = joints - shift, None if surface is None else surface - shift
        meta["placed"] = f"moved {-lowest:+.3f} m along y to stand on the floor"
    body = {"vertices": surface, "faces": model.faces} if with_vertices else {}
    skeleton = hands_skeleton() if hands else "smpl22"
    return Motion(joints.astype(np.float32), skeleton, fps, action or UNKNOWN_ACTION, source,
                  meta=meta, **body)


UPS = ("y", "-y", "z", "-z")


def _up_turn(joints: np.ndarray) -> np.ndarray:
    """Return the rotation taking the body's up axis (among y and z, either sign) onto y."""
    rise = joints[:, HEAD] - joints[:, list(ANKLES)].mean(axis=1)
    heights = {axis: float(np.median(rise[:, "xyz".index(axis[-1])])) *
               (-1 if axis.startswith("-") else 1) for axis in UPS}
    return axis_rotation(max(heights, key=heights.get), "y").astype(np.float32)


def _axis_name(turn: np.ndarray) -> str:
    return next(axis for axis in UPS if np.allclose(axis_rotation(axis, "y"), turn))


def detect(probe) -> str | None:
    """Recognise SMPL-X's 165 pose values in an .npz, or Motion-X's (T, 322) array."""
    if probe.suffix == ".npy" and probe.shape is not None and len(probe.shape) == 2 \
            and probe.shape[1] == MOTION_X:
        return f"an array of shape {probe.shape}: Motion-X's SMPL-X parameters"
    if probe.suffix == ".npz" and "poses" in probe.keys:
        shape = probe.member_shape("poses")
        if shape is not None and len(shape) == 2 and shape[1] == WIDTH:
            layout = "AMASS SMPL-X" if "surface_model_type" in probe.keys else "BEAT2/EMAGE"
            return f"an .npz with poses {shape}: SMPL-X ({layout})"
    return None


format_module(__name__, "smplx")  # the module's name keeps the smplx package's free

"""AMASS motions: SMPL+H (or SMPL) pose parameters in ``.npz`` files, posed with smplx.

An AMASS file holds ``poses`` ``(T, 156)`` axis-angle (the root, 21 body joints, then 30
hand joints: SMPL+H) or ``(T, 72)`` (SMPL's 24 joints), ``trans`` ``(T, 3)``, ``betas``
(shape, usually 16), ``gender`` and ``mocap_framerate`` (newer releases:
``mocap_frame_rate``). AMASS is z up, metres. The joints come from the body model
the user supplies (see :mod:`motion.body_models`): SMPL+H gives ``smpl22`` (its 22
body joints), SMPL gives ``smpl24``; both turned onto y up. The body surface is kept
unless ``vertices`` is false. Files without ``poses`` (AMASS's ``shape.npz``) are
reported and skipped.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.body_models import BodyModelError, load_body_model
from motion.formats.base import (
    FormatError,
    MotionList,
    check_finite,
    check_shape,
    files_in,
    format_module,
    load_each,
    need_keys,
    read_npz,
)
from motion.motion import UNKNOWN_ACTION, Motion
from motion.ops import axis_rotation

LAYOUT = ("an AMASS .npz: poses (T, 156) or (T, 72) axis-angle, trans (T, 3), betas, gender, "
          "mocap_framerate")
KINDS = {156: ("smplh", "smpl22"), 72: ("smpl", "smpl24")}
CHUNK = 256  # frames posed at once, to bound memory on long takes


def load(path: str | Path, body_models: str | Path | None = None, gender: str | None = None,
         action: str | None = None, vertices: bool = True, source: str = "real") -> list[Motion]:
    """Read AMASS files (a file or a folder of them) through the user's body models."""
    files = files_in(Path(path), ("*.npz",), LAYOUT)
    return load_each(files, lambda file: MotionList([_one(file, body_models, gender, action,
                                                          vertices, source)]), "AMASS file")


def _one(path: Path, body_models, gender, action, with_vertices: bool, source: str) -> Motion:
    data = read_npz(path, "AMASS pose parameters", objects=True)
    need_keys(data, ("poses", "trans"), path, LAYOUT)
    poses = check_shape(data["poses"], lambda s: len(s) == 2 and s[1] in KINDS and s[0] > 0,
                        path, "poses", "(T, 156) (SMPL+H) or (T, 72) (SMPL) axis-angle")
    frames = len(poses)
    trans = check_shape(data["trans"], lambda s: s == (frames, 3), path, "trans",
                        f"({frames}, 3), one root translation per frame of poses")
    check_finite(poses, path, "poses")
    check_finite(trans, path, "trans")
    rate = data.get("mocap_framerate", data.get("mocap_frame_rate"))
    if rate is None:
        raise FormatError(f"{path}: no key 'mocap_framerate' (nor 'mocap_frame_rate'); "
                          f"expected {LAYOUT}")
    kind, skeleton = KINDS[poses.shape[1]]
    sex = gender or _gender(data.get("gender"))
    try:
        model = load_body_model(kind, sex, body_models)
    except BodyModelError as exc:
        raise FormatError(f"{path}: {exc}") from None
    betas = data.get("betas")
    joints, surface = [], []
    for start in range(0, frames, CHUNK):
        part = slice(start, start + CHUNK)
        if kind == "smplh":
            posed = model.forward(poses[part, :3], poses[part, 3:66], trans[part], betas,
                                  hand_pose=poses[part, 66:156])
        else:
            posed = model.forward(poses[part, :3], poses[part, 3:72], trans[part], betas)
        joints.append(posed[0])
        if with_vertices:
            surface.append(posed[1])
    up = axis_rotation("z", "y").astype(np.float32)  # AMASS is z up; smpl22/24 are y up
    body = {}
    if with_vertices:
        body = {"vertices": np.concatenate(surface) @ up.T, "faces": model.faces}
    return Motion(np.concatenate(joints) @ up.T, skeleton, float(rate), action or UNKNOWN_ACTION,
                  source, meta={"file": str(path), "gender": sex, "body_model": str(model.path)},
                  **body)


def _gender(value) -> str:
    if value is None:
        return "neutral"
    value = np.asarray(value).item()
    value = value.decode() if isinstance(value, bytes) else str(value)
    return value.strip().lower() or "neutral"


def detect(probe) -> str | None:
    """Recognise AMASS's SMPL+H or SMPL ``.npz`` (not its SMPL-X release)."""
    if probe.suffix != ".npz" or not {"poses", "trans"} <= probe.keys:
        return None
    shape = probe.member_shape("poses")
    kind = probe.member("surface_model_type")
    if kind is not None and "smplx" in str(np.asarray(kind).item()).lower():
        return None
    if shape is not None and len(shape) == 2 and shape[1] in KINDS:
        return (f"an .npz with poses {shape} and trans: AMASS "
                f"{'SMPL+H' if shape[1] == 156 else 'SMPL'}")
    return None


format_module(__name__)

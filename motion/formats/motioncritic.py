"""MotionCritic / MotionPercept motion files: four MDM motions per ``.npz``.

Each file's ``arr_0`` is a dict with ``prompt`` (4 prompts, one per choice A-D) and
``motion`` (4 arrays of shape ``(1, 25, 6, 60)``: 6D rotations of SMPL's 24 joints and
the root translation, as MDM's action models write them, see
:mod:`motion.formats.smpl_poses`). They are posed with the user's SMPL model into
``smpl24`` joints (and the body surface, unless ``vertices`` is false), at 20 fps
(HumanAct12's rate; ``file_fps`` for another). Each motion's ``text`` and ``action``
are its prompt; ``meta["choice"]`` is its letter.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.body_models import BodyModelError
from motion.formats.base import (
    FormatError,
    MotionList,
    files_in,
    finite_only,
    format_module,
    load_each,
    need_keys,
    pickled_dict,
    read_npz,
)
from motion.formats.smpl_poses import pose_rot6d, stand_upright
from motion.motion import UNKNOWN_ACTION, Motion

LAYOUT = ("a MotionCritic .npz: arr_0, a dict with prompt (4 prompts) and motion "
          "(4 arrays of shape (1, 25, 6, 60))")
SOURCE = "motioncritic"


def load(path: str | Path, body_models: str | Path | None = None, file_fps: float | None = None,
         vertices: bool = True, source: str = SOURCE) -> list[Motion]:
    """Read MotionCritic files (a file or a folder of them)."""
    files = files_in(Path(path), ("*.npz",), LAYOUT)
    return load_each(files, lambda f: _one(f, body_models, file_fps, vertices, source),
                     "MotionCritic file")


def read(path: Path) -> dict:
    """Return the dict of a MotionCritic file, checked for its keys."""
    arrays = read_npz(path, "MotionCritic motions", objects=True)
    need_keys(arrays, ("arr_0",), path, LAYOUT)
    data = pickled_dict(arrays["arr_0"], path, LAYOUT)
    need_keys(data, ("prompt", "motion"), path, LAYOUT)
    return data


def _one(path: Path, body_models, file_fps, with_vertices: bool, source: str) -> MotionList:
    data = read(path)
    prompts, motions = list(data["prompt"]), list(data["motion"])
    if len(prompts) != len(motions):
        raise FormatError(f"{path}: {len(prompts)} prompts for {len(motions)} motions; "
                          f"expected {LAYOUT}")
    result = []
    for index, (prompt, motion) in enumerate(zip(prompts, motions)):
        motion = np.asarray(motion)
        if motion.ndim == 4 and motion.shape[0] == 1:
            motion = motion[0]
        try:
            joints, surface, faces = pose_rot6d(motion, body_models, path, f"motion[{index}]")
        except BodyModelError as exc:
            raise FormatError(f"{path}: {exc}") from None
        joints, surface, _ = stand_upright(joints, surface)
        text = str(prompt).strip() or None
        body = {"vertices": surface, "faces": faces} if with_vertices else {}
        result.append(Motion(joints, "smpl24", file_fps or 20.0, text or UNKNOWN_ACTION, source,
                             meta={"file": str(path), "choice": "ABCD"[index % 4]}, text=text,
                             **body))
    return finite_only(result, path)


def detect(probe) -> str | None:
    """Recognise MotionCritic's ``.npz``: ``arr_0`` holding prompt and motion."""
    if probe.suffix == ".npz" and "arr_0" in probe.keys:
        content = probe.member("arr_0")
        if isinstance(content, dict) and {"prompt", "motion"} <= set(content):
            return "an .npz whose arr_0 holds prompt and motion (MotionCritic)"
    return None


format_module(__name__)

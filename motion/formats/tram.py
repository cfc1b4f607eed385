"""TRAM's per-track results: SMPL rotations and the root's path in the world frame.

TRAM saves one file per track (``hps_track_<i>.npy``, an ``np.save`` of a dict, its
values often torch tensors): ``pred_rotmat`` ``(T, 24, 3, 3)`` rotation matrices,
``pred_trans`` ``(T, 3)`` (or ``(T, 1, 3)``) and ``pred_shape`` ``(T, 10)``, with the
camera motion its SLAM step estimated already applied (the world frame). ``file_fps``
(default 30) is the video's rate. Posed with the user's SMPL model, stood upright and on
the floor (:mod:`motion.formats.smpl_estimates`).
"""

from __future__ import annotations

from pathlib import Path

from motion.formats.base import (
    FormatError,
    MotionList,
    files_in,
    format_module,
    load_each,
    need_keys,
)
from motion.formats.smpl_estimates import array, axis_angles, pose, read_data

LAYOUT = ("TRAM's track file: a dict with pred_rotmat (T, 24, 3, 3), pred_trans (T, 3), "
          "pred_shape (T, 10)")
FPS = 30.0
PATTERNS = ("*.npy", "*.pkl", "*.pt")


def load(path: str | Path, body_models: str | Path | None = None,
         file_fps: float | None = None, action: str | None = None, vertices: bool = True,
         source: str = "real") -> list:
    """Read TRAM track files (a file, or a folder of them) through the user's SMPL model."""
    files = files_in(Path(path), PATTERNS, LAYOUT)
    return load_each(files, lambda file: MotionList([_one(file, body_models, file_fps or FPS,
                                                          action, vertices, source)]),
                     "TRAM file")


def _one(path: Path, body_models, fps, action, vertices, source):
    data = read_data(path, LAYOUT)
    if not isinstance(data, dict):
        raise FormatError(f"{path}: holds {type(data).__name__}; expected {LAYOUT}")
    need_keys(data, ("pred_rotmat", "pred_trans"), path, LAYOUT)
    rotations = array(data["pred_rotmat"], path, "pred_rotmat", "(T, 24, 3, 3)",
                      lambda s: len(s) == 4 and s[1:] == (24, 3, 3) and s[0] > 0)
    frames = len(rotations)
    trans = array(data["pred_trans"], path, "pred_trans", f"({frames}, 3)",
                  lambda s: s in ((frames, 3), (frames, 1, 3)))
    return pose(path, axis_angles(rotations), trans, data.get("pred_shape"), fps,
                body_models=body_models, frame="world", action=action, source=source,
                vertices=vertices)


def detect(probe) -> str | None:
    """Recognise TRAM's dict of pred_rotmat and pred_trans."""
    if probe.suffix in (".npy", ".pkl", ".pt") and {"pred_rotmat", "pred_trans"} <= probe.keys:
        return "a dict with pred_rotmat and pred_trans (world frame): TRAM's track file"
    return None


format_module(__name__)

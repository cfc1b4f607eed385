"""PHC motion libraries: a joblib dict of clips of SMPL parameters, z up.

PHC (and the humanoid simulation work built on it) keeps its training motions as one
joblib file: a dict by clip name of dicts with ``pose_aa`` ``(T, 72)`` (or
``(T, 24, 3)``) axis-angle in SMPL's joint order, often a torch tensor, ``trans`` and
``root_trans_offset`` ``(T, 3)``, ``beta``, ``gender`` and ``fps`` (30), in a z-up
world with the floor at zero. Each clip becomes a motion (its name in
``meta["clip"]``), posed with the user's SMPL model and turned onto y up.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.formats.base import FormatError, MotionList, files_in, format_module, load_each
from motion.formats.smpl_estimates import array, pose, read_data

LAYOUT = ("a PHC motion library (joblib): {clip name: {pose_aa (T, 72), trans (T, 3), "
          "root_trans_offset, beta, gender, fps}}")
FPS = 30.0


def clips_of(data) -> dict:
    """Return the clips of a motion library (dicts with pose_aa and a translation)."""
    if not isinstance(data, dict):
        return {}
    return {key: value for key, value in data.items() if isinstance(value, dict)
            and "pose_aa" in value and {"trans", "root_trans_offset"} & set(value)}


def load(path: str | Path, body_models: str | Path | None = None, action: str | None = None,
         vertices: bool = True, source: str = "real") -> list:
    """Read PHC motion libraries (a file, or a folder of them) through the SMPL model."""
    files = files_in(Path(path), ("*.pkl", "*.joblib"), LAYOUT)
    return load_each(files, lambda file: _one(file, body_models, action, vertices, source),
                     "PHC motion library")


def _one(path: Path, body_models, action, vertices, source) -> MotionList:
    clips = clips_of(read_data(path, LAYOUT))
    if not clips:
        raise FormatError(f"{path}: no clip with pose_aa and trans; expected {LAYOUT}")
    result = MotionList()
    for name, clip in clips.items():
        poses = array(clip["pose_aa"], path, f"[{name!r}].pose_aa", "(T, 72) or (T, 24, 3)",
                      lambda s: len(s) in (2, 3) and int(np.prod(s[1:])) == 72 and s[0] > 0)
        poses = poses.reshape(len(poses), 72)
        key = "trans" if "trans" in clip else "root_trans_offset"
        trans = array(clip[key], path, f"[{name!r}].{key}", f"({len(poses)}, 3)",
                      lambda s: s == (len(poses), 3))
        fps = float(np.asarray(clip.get("fps", FPS)).reshape(-1)[0])
        gender = clip.get("gender", "neutral")
        gender = gender if isinstance(gender, str) and gender in ("male", "female") else "neutral"
        result.append(pose(path, poses, trans, clip.get("beta"), fps, body_models=body_models,
                           gender=gender, up="z", frame="world", action=action,
                           source=source, vertices=vertices, meta={"clip": str(name)}))
    return result


def detect(probe) -> str | None:
    """Recognise a PHC motion library by its clips."""
    if probe.suffix in (".pkl", ".joblib") and clips_of(probe.content):
        return f"{len(clips_of(probe.content))} clips with pose_aa and trans: a PHC motion library"
    return None


format_module(__name__)

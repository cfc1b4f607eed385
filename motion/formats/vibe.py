"""VIBE's ``vibe_output.pkl``: SMPL parameters per tracked person, in the camera's frame.

VIBE's demo writes a joblib file: a dict by person id of dicts with ``pose`` ``(T, 72)``
axis-angle, ``betas`` ``(T, 10)``, ``frame_ids``, ``joints3d`` ``(T, 49, 3)``,
``pred_cam``, ``orig_cam`` (weak-perspective cameras) and ``verts``; no root
translation, so each motion turns in place. ``person`` picks one track (default: every
track); ``file_fps`` (default 30) is the video's rate. Posed with the user's SMPL model,
stood upright and on the floor (:mod:`motion.formats.smpl_estimates`).
"""

from __future__ import annotations

from pathlib import Path

from motion.formats.base import FormatError, MotionList, files_in, format_module, load_each
from motion.formats.smpl_estimates import array, choose, pose, read_data

LAYOUT = ("VIBE's vibe_output.pkl: {person id: {pose (T, 72), betas (T, 10), frame_ids, "
          "joints3d, pred_cam, orig_cam, verts}}")
FPS = 30.0


def tracks_of(data) -> dict:
    """Return VIBE's person tracks: dicts with pose and a camera or joints, no trans."""
    if not isinstance(data, dict):
        return {}
    return {key: value for key, value in data.items() if isinstance(value, dict)
            and "pose" in value and "trans" not in value
            and {"joints3d", "pred_cam", "orig_cam"} & set(value)}


def load(path: str | Path, body_models: str | Path | None = None, person: str | None = None,
         file_fps: float | None = None, action: str | None = None, vertices: bool = True,
         source: str = "real") -> list:
    """Read VIBE outputs (a file, or a folder of them) through the user's SMPL model."""
    files = files_in(Path(path), ("*.pkl",), LAYOUT)
    return load_each(files, lambda file: _one(file, body_models, person, file_fps or FPS,
                                              action, vertices, source), "VIBE file")


def _one(path: Path, body_models, person, fps, action, vertices, source) -> MotionList:
    tracks = tracks_of(read_data(path, LAYOUT))
    if not tracks:
        raise FormatError(f"{path}: no person with pose and a camera; expected {LAYOUT}")
    chosen = choose(tracks, person, path)
    result = MotionList(notes=[f"{path}: {len(tracks)} tracked people "
                               f"({', '.join(map(str, tracks))}); importing "
                               f"{', '.join(map(str, chosen))} in the camera frame, without "
                               "root translation"])
    for key in chosen:
        poses = array(tracks[key]["pose"], path, f"[{key}].pose", "(T, 72)",
                      lambda s: len(s) == 2 and s[1] == 72 and s[0] > 0)
        result.append(pose(path, poses, None, tracks[key].get("betas"), fps,
                           body_models=body_models, frame="camera", action=action,
                           source=source, vertices=vertices, meta={"person": str(key)}))
    return result


def detect(probe) -> str | None:
    """Recognise VIBE's output by its person dicts."""
    if probe.suffix in (".pkl", ".joblib") and tracks_of(probe.content):
        return "person tracks with pose, cameras and no trans: VIBE's vibe_output.pkl"
    return None


format_module(__name__)

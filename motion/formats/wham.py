"""WHAM's ``output.pkl``: SMPL parameters per tracked person, in the world and camera frames.

WHAM's demo writes a joblib file: a dict by person id of dicts with ``pose`` ``(T, 72)``
and ``trans`` ``(T, 3)`` (the camera frame), ``pose_world`` and ``trans_world`` (the
world frame WHAM estimates, gravity aligned), ``betas``, ``verts`` and ``frame_ids``.
``frame`` picks ``world`` (the default) or ``camera``; ``person`` one track (default:
every track, each a motion). The file holds no frame rate: ``file_fps`` (default 30,
the video's usual rate). Posed with the user's SMPL model, stood upright and on the
floor (:mod:`motion.formats.smpl_estimates`).
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
from motion.formats.smpl_estimates import array, choose, pose, read_data

LAYOUT = ("WHAM's output.pkl: {person id: {pose (T, 72), trans (T, 3), pose_world (T, 72), "
          "trans_world (T, 3), betas, verts, frame_ids}}")
FPS = 30.0
FRAMES = ("world", "camera")


def tracks_of(data) -> dict:
    """Return the person tracks of WHAM's output (dicts with pose and trans)."""
    if not isinstance(data, dict):
        return {}
    return {key: value for key, value in data.items()
            if isinstance(value, dict) and {"pose", "trans"} <= set(value)}


def load(path: str | Path, body_models: str | Path | None = None, person: str | None = None,
         frame: str = "world", file_fps: float | None = None, action: str | None = None,
         vertices: bool = True, source: str = "real") -> list:
    """Read WHAM outputs (a file, or a folder of them) through the user's SMPL model."""
    if frame not in FRAMES:
        raise FormatError(f"frame {frame!r}: WHAM's outputs are in the {' or '.join(FRAMES)} "
                          "frame")
    files = files_in(Path(path), ("*.pkl",), LAYOUT)
    return load_each(files, lambda file: _one(file, body_models, person, frame,
                                              file_fps or FPS, action, vertices, source),
                     "WHAM file")


def _one(path: Path, body_models, person, frame, fps, action, vertices, source) -> MotionList:
    tracks = tracks_of(read_data(path, LAYOUT))
    if not tracks:
        raise FormatError(f"{path}: no person with pose and trans; expected {LAYOUT}")
    chosen = choose(tracks, person, path)
    suffix = "_world" if frame == "world" else ""
    result = MotionList(notes=[f"{path}: {len(tracks)} tracked people "
                               f"({', '.join(map(str, tracks))}); importing "
                               f"{', '.join(map(str, chosen))} in the {frame} frame"
                               f"{' (--person ID picks one)' if len(tracks) > 1 else ''}"])
    for key in chosen:
        track = tracks[key]
        need_keys(track, (f"pose{suffix}", f"trans{suffix}"), path, LAYOUT)
        poses = array(track[f"pose{suffix}"], path, f"[{key}].pose{suffix}", "(T, 72)",
                      lambda s: len(s) == 2 and s[1] == 72 and s[0] > 0)
        trans = array(track[f"trans{suffix}"], path, f"[{key}].trans{suffix}",
                      f"({len(poses)}, 3)", lambda s: s in ((len(poses), 3), (len(poses), 1, 3)))
        result.append(pose(path, poses, trans, track.get("betas"), fps, body_models=body_models,
                           frame=frame, action=action, source=source, vertices=vertices,
                           meta={"person": str(key)}))
    return result


def detect(probe) -> str | None:
    """Recognise WHAM's output: person dicts with pose and trans."""
    if probe.suffix in (".pkl", ".joblib") and tracks_of(probe.content):
        frames = "world and camera" if any("pose_world" in t for t in
                                          tracks_of(probe.content).values()) else "camera"
        return f"person tracks with pose and trans ({frames} frame): WHAM's output.pkl"
    return None


format_module(__name__)

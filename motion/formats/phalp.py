"""4D-Humans (PHALP) tracking results: per video frame, the SMPL parameters of each track.

``track.py`` of 4D-Humans writes a joblib file: a dict by frame name of dicts with
``time``, ``tracked_ids`` (the people seen in that frame), and, one entry per tracked
id, ``smpl`` (dicts of ``global_orient`` ``(1, 3, 3)``, ``body_pose`` ``(23, 3, 3)``
rotation matrices and ``betas`` ``(10,)``) and ``camera`` (the person's translation in
the camera frame). Each id becomes one motion of the frames it was seen in (in time
order); ``person`` picks one id. ``file_fps`` (default 30) is the video's rate. Posed
with the user's SMPL model, stood upright and on the floor
(:mod:`motion.formats.smpl_estimates`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.formats.base import (
    FormatError,
    MotionList,
    files_in,
    format_module,
    load_each,
    natural_key,
)
from motion.formats.smpl_estimates import array, axis_angles, choose, pose, read_data

LAYOUT = ("4D-Humans/PHALP results .pkl: {frame name: {time, tracked_ids, smpl: [{global_orient "
          "(1, 3, 3), body_pose (23, 3, 3), betas}], camera: [(3,)]}}")
FPS = 30.0
MIN_FRAMES = 2


def frames_of(data) -> list:
    """Return the per-frame dicts (with tracked_ids and smpl) in time order."""
    if not isinstance(data, dict):
        return []
    frames = [(key, value) for key, value in data.items()
              if isinstance(value, dict) and {"tracked_ids", "smpl"} <= set(value)]
    frames.sort(key=lambda item: (item[1].get("time", 0), natural_key(Path(str(item[0])))))
    return [value for _, value in frames]


def load(path: str | Path, body_models: str | Path | None = None, person: str | None = None,
         file_fps: float | None = None, action: str | None = None, vertices: bool = True,
         source: str = "real") -> list:
    """Read 4D-Humans/PHALP results (a file, or a folder of them) through the SMPL model."""
    files = files_in(Path(path), ("*.pkl",), LAYOUT)
    return load_each(files, lambda file: _one(file, body_models, person, file_fps or FPS,
                                              action, vertices, source), "PHALP file")


def _one(path: Path, body_models, person, fps, action, vertices, source) -> MotionList:
    frames = frames_of(read_data(path, LAYOUT))
    if not frames:
        raise FormatError(f"{path}: no frame with tracked_ids and smpl; expected {LAYOUT}")
    tracks: dict = {}
    for index, frame in enumerate(frames):
        ids, smpl = list(frame["tracked_ids"]), list(frame["smpl"])
        cameras = list(frame.get("camera", [None] * len(ids)))
        if len(smpl) != len(ids):
            raise FormatError(f"{path}: frame {index} lists {len(ids)} tracked_ids but "
                              f"{len(smpl)} smpl entries; expected one per id")
        for track, params, camera in zip(ids, smpl, cameras + [None] * len(ids)):
            tracks.setdefault(int(track) if np.ndim(track) == 0 else str(track), []).append(
                (params, camera))
    chosen = [key for key in choose(tracks, person, path) if len(tracks[key]) >= MIN_FRAMES]
    if not chosen:
        raise FormatError(f"{path}: every track is shorter than {MIN_FRAMES} frames")
    result = MotionList(notes=[f"{path}: {len(tracks)} tracks over {len(frames)} frames "
                               f"({', '.join(f'{k}: {len(v)}' for k, v in tracks.items())} "
                               f"frames); importing {', '.join(map(str, chosen))} in the "
                               "camera frame"])
    for key in chosen:
        seen = tracks[key]
        rotations = np.stack([
            np.concatenate([array(p.get("global_orient"), path, f"track {key} global_orient",
                                  "(1, 3, 3)", lambda s: s == (1, 3, 3)),
                            array(p.get("body_pose"), path, f"track {key} body_pose",
                                  "(23, 3, 3)", lambda s: s == (23, 3, 3))])
            for p, _ in seen])
        trans = None
        if all(camera is not None for _, camera in seen):
            trans = np.stack([array(c, path, f"track {key} camera", "(3,)",
                                    lambda s: s in ((3,), (1, 3))).reshape(3) for _, c in seen])
        betas = np.stack([np.asarray(p.get("betas", np.zeros(10)), float).reshape(-1)
                          for p, _ in seen])
        result.append(pose(path, axis_angles(rotations), trans, betas, fps,
                           body_models=body_models, frame="camera", action=action,
                           source=source, vertices=vertices, meta={"person": str(key)}))
    return result


def detect(probe) -> str | None:
    """Recognise PHALP's per-frame dicts."""
    if probe.suffix in (".pkl", ".joblib") and frames_of(probe.content):
        return "per-frame dicts with tracked_ids and smpl: 4D-Humans/PHALP results"
    return None


format_module(__name__)

"""SMPL parameters from pose estimators and simulators, posed into ``smpl24`` motions.

What the estimator formats (``wham``, ``phalp``, ``vibe``, ``tram``) and the dataset and
simulator formats (``aistpp``, ``phc``) share: reading the file as data, choosing the
tracks (``person``), turning rotation matrices into axis-angle, posing SMPL with the
user's model (:mod:`motion.body_models`), and standing the result up.

Frames: an estimator's camera frame is y down (OpenCV), and its world frame has no known
floor; such motions are turned upright (180 degrees about x when the head is below the
feet) and lowered or raised so that their lowest joint rests on the floor (its median
over frames at y = 0). ``meta["frame"]`` says which frame the parameters were in
(``camera`` or ``world``), ``meta["placed"]`` what was done to stand it on the floor.
Datasets with a floor (AIST++ y up, PHC z up) keep their heights.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion import safe_load
from motion.body_models import BodyModelError, load_body_model, matrix_to_axis_angle
from motion.formats.base import FormatError, check_finite
from motion.formats.smpl_poses import stand_upright
from motion.motion import UNKNOWN_ACTION, Motion
from motion.ops import axis_rotation

CHUNK = 256  # frames posed at once


def read_data(path: Path, what: str):
    """Return what a pickle, joblib or ``.npy`` file holds, read as plain data."""
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"{path} does not exist; expected {what}")
    try:
        value = safe_load.load_data(path)
    except safe_load.RefusedObject as exc:
        raise FormatError(str(exc)) from None
    except safe_load.DataFileError as exc:
        raise FormatError(f"{exc}; expected {what}") from None
    if isinstance(value, np.ndarray) and value.dtype == object and value.shape == ():
        value = value.item()
    return value


def array(value, path: Path, key: str, shapes: str, check) -> np.ndarray:
    """Return ``value`` as a float array if ``check(shape)``, else raise naming the key."""
    if isinstance(value, dict) and "arr" in value:  # poselib's {"arr": ..., "context": ...}
        value = value["arr"]
    try:
        values = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError(f"{path}: {key} holds {type(value).__name__}; expected {shapes}") \
            from None
    if not check(values.shape):
        raise FormatError(f"{path}: {key} has shape {values.shape}; expected {shapes}")
    check_finite(values, path, key)
    return values


def axis_angles(rotations: np.ndarray) -> np.ndarray:
    """Return axis-angle ``(T, 24 * 3)`` of rotation matrices ``(T, 24, 3, 3)``."""
    return matrix_to_axis_angle(rotations).reshape(len(rotations), -1)


def choose(tracks: dict, person, path: Path) -> list:
    """Return the ids of ``tracks`` to import: ``person`` alone, else all of them."""
    if person is None:
        return list(tracks)
    matches = [key for key in tracks if str(key) == str(person)]
    if not matches:
        raise FormatError(f"{path}: no person {person!r}; the file's tracks are "
                          f"{', '.join(map(str, tracks))} (pass --person ID)")
    return matches


def pose(path: Path, poses: np.ndarray, transl: np.ndarray | None, betas, fps: float, *,
         body_models=None, gender: str = "neutral", up: str = "unknown",
         frame: str = "world", action: str | None = None, source: str = "real",
         text: str | None = None, vertices: bool = True, meta: dict | None = None,
         scale: float = 1.0) -> Motion:
    """Return the ``smpl24`` motion of axis-angle ``poses`` ``(T, 72)`` and ``transl``.

    ``up``: ``"y"`` or ``"z"`` for data with a floor at zero (kept), ``"unknown"`` for an
    estimator's frame (stood upright and put on the floor, see the module docstring).
    ``scale`` multiplies the posed body (AIST++ fits a scale per subject).
    """
    frames = len(poses)
    transl = np.zeros((frames, 3)) if transl is None else np.asarray(transl).reshape(frames, 3)
    betas = None if betas is None else np.asarray(betas, np.float64)
    if betas is not None and betas.ndim == 2:
        betas = betas.mean(axis=0)  # estimators give one shape per frame
    try:
        model = load_body_model("smpl", gender, body_models)
    except BodyModelError as exc:
        raise FormatError(f"{path}: {exc}") from None
    joints, surface = [], []
    for start in range(0, frames, CHUNK):
        part = slice(start, start + CHUNK)
        posed = model.forward(poses[part, :3], poses[part, 3:72], transl[part], betas)
        joints.append(posed[0])
        if vertices:
            surface.append(posed[1])
    joints = np.concatenate(joints) * np.float32(scale)
    surface = np.concatenate(surface) * np.float32(scale) if vertices else None
    info = {"file": str(path), "frame": frame, "body_model": str(model.path), **(meta or {})}
    if up == "z":
        turn = axis_rotation("z", "y").astype(np.float32)
        joints = joints @ turn.T
        surface = None if surface is None else surface @ turn.T
    elif up == "unknown":
        joints, surface, turned = stand_upright(joints, surface)
        lowest = float(np.median(joints[..., 1].min(axis=1)))
        joints = joints - np.array([0, lowest, 0], np.float32)
        surface = None if surface is None else surface - np.array([0, lowest, 0], np.float32)
        info["placed"] = (f"{'turned upright (180 degrees about x), ' if turned else ''}"
                          f"moved {-lowest:+.3f} m along y to stand on the floor")
    body = {"vertices": surface, "faces": model.faces} if vertices else {}
    return Motion(joints.astype(np.float32), "smpl24", float(fps), action or UNKNOWN_ACTION,
                  source, meta=info, text=text, **body)

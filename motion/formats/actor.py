"""ACTOR's ``generation.npy``: SMPL vertices ``(samples, actions, 6890, 3, T)``.

``src/generate/generate_sequences.py`` saves, for every action class, several generated
sequences as SMPL vertex positions (no translation). The file holds no joints, faces
or names: joints are regressed from the vertices and the faces taken from the user's
SMPL model (see :mod:`motion.body_models`), giving ``smpl24`` motions with their
body surface; like all of ACTOR's bodies they are y down and turned upright. Class
``k`` is ``action_names[k]``, by default HumanAct12's 12 classes when there are 12,
else ``class<k>``. ``file_fps`` defaults to 20 (HumanAct12's rate).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.body_models import BodyModelError, load_body_model
from motion.datasets.humanact12 import CLASSES
from motion.formats.base import FormatError, check_shape, finite_only, format_module, read_npy
from motion.formats.smpl_poses import stand_upright
from motion.motion import Motion

LAYOUT = "ACTOR's generation.npy: SMPL vertices of shape (samples, actions, 6890, 3, T)"
SOURCE = "actor"


def load(path: str | Path, body_models: str | Path | None = None, action_names=None,
         file_fps: float | None = None, source: str = SOURCE) -> list[Motion]:
    """Read ACTOR's generated vertices as motions with their bodies."""
    path = Path(path)
    if path.is_dir():
        path = path / "generation.npy"
    vertices = check_shape(read_npy(path, LAYOUT),
                           lambda s: len(s) == 5 and s[3] == 3 and min(s) > 0, path,
                           "vertices", "(samples, actions, V, 3, T)")
    samples, actions = vertices.shape[:2]
    names = list(action_names) if action_names is not None else (
        list(CLASSES) if actions == len(CLASSES) else [f"class{k}" for k in range(actions)])
    if len(names) != actions:
        raise FormatError(f"{path}: {actions} action classes but {len(names)} action names; "
                          "pass one name per class")
    try:
        model = load_body_model("smpl", "neutral", body_models)
        if vertices.shape[2] != model.regressor.shape[1]:
            raise FormatError(f"{path}: vertices of shape {vertices.shape} have "
                              f"{vertices.shape[2]} points; the SMPL model has "
                              f"{model.regressor.shape[1]}; expected {LAYOUT}")
    except BodyModelError as exc:
        raise FormatError(f"{path}: ACTOR's file has no faces or joints, which come from "
                          f"the SMPL model: {exc}") from None
    motions = []
    for sample in range(samples):
        for action in range(actions):
            surface = vertices[sample, action].transpose(2, 0, 1).astype(np.float32)
            joints = model.regress(surface)
            joints, surface, _ = stand_upright(joints, surface)
            motions.append(Motion(joints, "smpl24", file_fps or 20.0, names[action], source,
                                  meta={"file": str(path), "sample": sample, "class": action},
                                  vertices=surface, faces=model.faces))
    return finite_only(motions, path)


def detect(probe) -> str | None:
    """Recognise ACTOR's ``generation.npy``: vertices ``(S, A, V, 3, T)``."""
    shape = probe.shape
    if shape is not None and len(shape) == 5 and shape[3] == 3:
        return f"an array of shape {shape}: (samples, actions, vertices, 3, T) (ACTOR)"
    return None


format_module(__name__)

"""AIST++ SMPL motions: ``smpl_poses``, ``smpl_trans`` and ``smpl_scaling`` per dance.

Each ``motions/<sequence>.pkl`` of AIST++ is a dict with ``smpl_poses`` ``(T, 72)``
axis-angle, ``smpl_trans`` ``(T, 3)`` and ``smpl_scaling`` ``(1,)``, at 60 fps, y up,
in centimetres: as AIST++'s own code poses it, the body is SMPL's at translation
``smpl_trans / smpl_scaling``, scaled by ``smpl_scaling``; here then divided by 100 for
metres. The sequence name (``gBR_sBM_cAll_d04_mBR0_ch01``) starts with the genre code
(``gBR``: break), kept as the action unless ``action`` says otherwise.
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
    need_keys,
)
from motion.formats.smpl_estimates import array, pose, read_data

LAYOUT = "an AIST++ motion .pkl: smpl_poses (T, 72), smpl_trans (T, 3), smpl_scaling (1,)"
FPS = 60.0
GENRES = {"gBR": "break", "gPO": "pop", "gLO": "lock", "gMH": "middle hip-hop",
          "gLH": "LA hip-hop", "gHO": "house", "gWA": "waack", "gKR": "krump",
          "gJS": "street jazz", "gJB": "ballet jazz"}


def load(path: str | Path, body_models: str | Path | None = None, action: str | None = None,
         vertices: bool = True, source: str = "real") -> list:
    """Read AIST++ motion files (a file, or a folder of them) through the SMPL model."""
    files = files_in(Path(path), ("*.pkl",), LAYOUT)
    return load_each(files, lambda file: MotionList([_one(file, body_models, action, vertices,
                                                          source)]), "AIST++ file")


def _one(path: Path, body_models, action, vertices, source):
    data = read_data(path, LAYOUT)
    if not isinstance(data, dict):
        raise FormatError(f"{path}: holds {type(data).__name__}; expected {LAYOUT}")
    need_keys(data, ("smpl_poses", "smpl_trans"), path, LAYOUT)
    poses = array(data["smpl_poses"], path, "smpl_poses", "(T, 72)",
                  lambda s: len(s) == 2 and s[1] == 72 and s[0] > 0)
    trans = array(data["smpl_trans"], path, "smpl_trans", f"({len(poses)}, 3)",
                  lambda s: s == (len(poses), 3))
    scaling = float(np.asarray(data.get("smpl_scaling", 1.0), float).reshape(-1)[0])
    if not scaling > 0:
        raise FormatError(f"{path}: smpl_scaling is {scaling}; expected a positive scale")
    genre = GENRES.get(path.stem[:3])
    return pose(path, poses, trans / scaling, None, FPS, body_models=body_models, up="y",
                frame="world", action=action or genre, source=source, vertices=vertices,
                meta={"sequence": path.stem}, scale=scaling / 100.0)


def detect(probe) -> str | None:
    """Recognise an AIST++ motion by its keys."""
    if probe.suffix in (".pkl", ".joblib") and {"smpl_poses", "smpl_trans"} <= probe.keys:
        return "a dict with smpl_poses, smpl_trans and smpl_scaling: AIST++"
    return None


format_module(__name__)

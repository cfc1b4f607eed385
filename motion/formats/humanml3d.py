"""HumanML3D's joint files: ``new_joints/<id>.npy`` ``(T, 22, 3)`` with ``texts/<id>.txt``.

The layout (KIT-ML in HumanML3D's processing is the same with 21 joints in
millimetres): a folder with ``new_joints/`` (joint positions, y up, metres, 20 fps;
KIT-ML 12.5 fps) and ``texts/``, one caption per line as ``caption#tokens#start#end``:
``start`` and ``end`` are seconds, both ``0.0`` when the caption describes the whole
clip. Each motion's ``text`` is its first whole-clip caption (else its first caption);
``meta["captions"]`` keeps every caption of the file with its span.

``path`` may be the dataset folder, its ``new_joints`` folder, or one ``.npy`` file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion.formats.base import (
    FormatError,
    MotionList,
    check_finite,
    check_shape,
    files_in,
    format_module,
    load_each,
    read_npy,
    skeleton_for,
)
from motion.motion import UNKNOWN_ACTION, Motion

SKELETONS = {22: "smpl22", 21: "kit21"}
FPS = {"smpl22": 20.0, "kit21": 12.5}
LAYOUT = ("HumanML3D's layout: new_joints/<id>.npy of shape (T, 22, 3) (KIT-ML: 21 joints) "
          "and texts/<id>.txt lines caption#tokens#start#end")


@dataclass(frozen=True)
class Caption:
    """One line of a HumanML3D text file; ``start == end == 0`` covers the whole clip."""

    text: str
    start: float = 0.0
    end: float = 0.0

    @property
    def whole(self) -> bool:
        return self.start == 0.0 and self.end == 0.0


def read_captions(path: Path) -> list[Caption]:
    """Return the captions of a HumanML3D text file (``caption#tokens#start#end`` lines)."""
    captions = []
    for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace")
                                  .splitlines(), 1):
        if not line.strip():
            continue
        parts = line.strip().split("#")
        start = end = 0.0
        if len(parts) >= 4:
            try:
                start, end = float(parts[2] or 0), float(parts[3] or 0)
            except ValueError:
                raise FormatError(f"{path}, line {number}: start and end must be seconds; got "
                                  f"{parts[2]!r} and {parts[3]!r} (lines are "
                                  "caption#tokens#start#end)") from None
            start, end = (0.0, 0.0) if np.isnan(start) or np.isnan(end) else (start, end)
        captions.append(Caption(parts[0].strip(), start, end))
    return captions


def caption_of(captions: list[Caption]) -> str | None:
    """Return the caption a clip is shown with: the first whole-clip one, else the first."""
    whole = [c for c in captions if c.whole]
    chosen = (whole or captions or [None])[0]
    return chosen.text if chosen else None


def texts_folder(path: Path, data_folder: str) -> Path | None:
    """Return the ``texts`` folder beside the ``data_folder`` that holds ``path``."""
    for folder in [path] + list(path.parents):
        if folder.name == data_folder and (folder.parent / "texts").is_dir():
            return folder.parent / "texts"
        if (folder / data_folder).is_dir() and (folder / "texts").is_dir():
            return folder / "texts"
    return None


def data_files(path: Path, data_folder: str, what: str) -> list[Path]:
    """Return the ``.npy`` files of a HumanML3D-layout folder, its data folder, or a file."""
    path = Path(path)
    if path.is_dir() and (path / data_folder).is_dir():
        path = path / data_folder
    return files_in(path, ("*.npy",), what)


def load(path: str | Path, skeleton: str | None = None, action: str | None = None,
         file_fps: float | None = None, source: str = "real") -> list[Motion]:
    """Read HumanML3D joint files with their captions (see the module docstring)."""
    path = Path(path)
    files = data_files(path, "new_joints", LAYOUT)
    texts = texts_folder(files[0], "new_joints")

    def one(file: Path) -> MotionList:
        joints = check_shape(read_npy(file, "joints (T, 22, 3)"),
                             lambda s: len(s) == 3 and s[2] == 3 and s[0] > 0, file, "joints",
                             "(T, J, 3): T frames of 22 (HumanML3D) or 21 (KIT-ML) joints")
        check_finite(joints, file, "joints")
        name = skeleton_for(joints.shape[1], skeleton, file, joints.shape, SKELETONS)
        return MotionList([motion_of(file, joints, name, texts, action, file_fps, source)])

    return load_each(files, one, "HumanML3D joint file")


def motion_of(file: Path, joints: np.ndarray, skeleton: str, texts: Path | None, action,
              file_fps, source: str) -> Motion:
    """Return the motion of one clip, with its captions when its text file exists."""
    captions = []
    if texts is not None and (texts / f"{file.stem}.txt").is_file():
        captions = read_captions(texts / f"{file.stem}.txt")
    meta = {"file": str(file), "id": file.stem,
            "captions": [(c.text, c.start, c.end) for c in captions]}
    return Motion(joints.astype(np.float32), skeleton, file_fps or FPS[skeleton],
                  action or UNKNOWN_ACTION, source, meta=meta, text=caption_of(captions))


def detect(probe) -> str | None:
    """Recognise a HumanML3D folder with ``new_joints/`` (its files alone are ``joints``)."""
    if probe.path.is_dir() and (probe.path.name == "new_joints"
                                or (probe.path / "new_joints").is_dir()):
        return "a new_joints/ folder (HumanML3D's layout)"
    return None


format_module(__name__)

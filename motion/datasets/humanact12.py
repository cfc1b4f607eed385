"""The ``humanact12`` dataset: HumanAct12 in the Action2Motion layout, 24 joints, y up.

The root is a folder of ``.npy`` files of shape ``(T, 24, 3)`` at 20 fps whose names end
in ``A<4-digit action code>`` (``P01G01R01F0069T0143A0102.npy``); the code's first two
digits are the coarse class 01-12. ``P<nn>`` at the start names the performer, kept in
``meta["subject"]`` (the dataset has no subject split).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from motion.datasets.base import Dataset, DatasetError, LoadReport, register_dataset
from motion.motion import Motion

# Action2Motion's coarse HumanAct12 labels, classes 1..12.
CLASSES = ("warm_up", "walk", "run", "jump", "drink", "lift_dumbbell", "sit", "eat",
           "turn_steering_wheel", "phone", "boxing", "throw")
NAME = re.compile(r"A(\d{2})(\d{2})$")
PERFORMER = re.compile(r"^(P\d+)")
LAYOUT = ("a folder of .npy files of shape (T, 24, 3) whose names end in A<4-digit action "
          "code>, e.g. P01G01R01F0069T0143A0102.npy (code 01xx-12xx)")


@register_dataset("humanact12")
class HumanAct12(Dataset):
    """HumanAct12 joint positions (SMPL's 24 joints), y up, 20 fps, 12 coarse classes."""

    skeleton = "humanact12"
    fps = 20.0
    clip_frames = 60
    clip_fps = 20.0
    subjects = None
    env_var = "STUDY_HUMANACT12_ROOT"
    default_dir = None

    def actions(self) -> list[str]:
        """Return the 12 coarse classes, in class-code order."""
        return list(CLASSES)

    def files(self) -> list[Path]:
        """Return the .npy files under the root, sorted by name."""
        root = self.data_root
        if root is None:
            raise DatasetError(
                f"HumanAct12 has no default folder; pass --data-root DIR or set "
                f"{self.env_var}, DIR being {LAYOUT}"
            )
        if not Path(root).is_dir():
            raise DatasetError(
                f"HumanAct12 folder {root} not found; expected {LAYOUT}; pass --data-root DIR "
                f"or set {self.env_var}"
            )
        files = sorted(Path(root).rglob("*.npy"), key=lambda p: (p.name, str(p)))
        if not files:
            raise DatasetError(f"no .npy files in {root}; expected {LAYOUT}")
        return files

    def load_takes(self, subjects=None, actions=None) -> LoadReport:
        """Return whole takes at 20 fps, and one line per malformed file."""
        self.check_subjects(subjects)
        wanted = set(self.check_actions(actions))
        report = LoadReport()
        files = self.files()
        for path in files:
            try:
                action = class_of(path)
                if action not in wanted:
                    continue
                joints = read_take(path)
            except DatasetError as exc:
                report.problems.append(str(exc))
                continue
            performer = PERFORMER.match(path.stem)
            meta = {"dataset": self.name, "subject": performer.group(1) if performer else None,
                    "take": path.stem}
            report.motions.append(Motion(joints, "humanact12", self.fps, action, meta=meta))
        if not report.motions and len(report.problems) == len(files):
            raise DatasetError(
                f"no valid HumanAct12 file in {self.data_root} ({len(files)} malformed, e.g. "
                f"{report.problems[0]}); expected {LAYOUT}"
            )
        return report


def class_of(path: Path) -> str:
    """Return the coarse class of a file from the action code ending its name."""
    match = NAME.search(path.stem)
    if not match or not 1 <= int(match.group(1)) <= len(CLASSES):
        raise DatasetError(
            f"{path}: name does not end in A<4-digit action code> with a class 01-12; "
            f"expected {LAYOUT}"
        )
    return CLASSES[int(match.group(1)) - 1]


def read_take(path: Path) -> np.ndarray:
    """Return a file's joints (T, 24, 3), or raise DatasetError saying what is wrong."""
    try:
        joints = np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for a damaged file
        raise DatasetError(f"{path}: not a readable .npy file ({exc}); expected {LAYOUT}") from exc
    if joints.ndim != 3 or joints.shape[1:] != (24, 3) or len(joints) == 0:
        raise DatasetError(f"{path}: shape {joints.shape}; expected (T, 24, 3)")
    if not np.isfinite(joints).all():
        raise DatasetError(f"{path}: non-finite joint coordinates")
    return joints.astype(np.float32)

"""``humanml3d`` and ``kit_ml``: real clips with captions, in HumanML3D's layout.

The root holds ``new_joints/<id>.npy`` (``(T, 22, 3)``, y up, metres, 20 fps; KIT-ML:
21 joints in millimetres at 12.5 fps) and ``texts/<id>.txt`` (lines
``caption#tokens#start#end``, see :mod:`motion.formats.humanml3d`). A caption with
a span (``start``/``end`` in seconds, not both 0) describes that part of the clip only:
as in HumanML3D's own loader it becomes a take of its own, cut to the span. Every take's
``text`` is its caption, so real clips for a prompt can be drawn with
:meth:`HumanML3D.takes_for`. The datasets have no action labels: every take's action is
``unknown``.
"""

from __future__ import annotations

import re
from pathlib import Path

from motion.datasets.base import Dataset, DatasetError, LoadReport, register_dataset
from motion.formats.base import FormatError, read_npy
from motion.formats.humanml3d import caption_of, read_captions
from motion.motion import UNKNOWN_ACTION, Motion

LAYOUT = ("a folder with new_joints/<id>.npy of shape (T, J, 3) and texts/<id>.txt lines "
          "caption#tokens#start#end (HumanML3D's layout)")


def normalise(prompt: str) -> str:
    """Return a prompt compared ignoring case, spacing and a final full stop."""
    return re.sub(r"\s+", " ", prompt.strip().lower()).rstrip(" .")


@register_dataset("humanml3d")
class HumanML3D(Dataset):
    """HumanML3D's joints (SMPL's first 22, y up, metres) at 20 fps, with their captions."""

    skeleton = "smpl22"
    fps = 20.0
    clip_frames = 60
    clip_fps = 20.0
    subjects = None
    env_var = "STUDY_HUMANML3D_ROOT"
    default_dir = None
    n_joints = 22

    def actions(self) -> list[str]:
        """Return the one action label of captioned clips, ``unknown``."""
        return [UNKNOWN_ACTION]

    def files(self) -> list[Path]:
        root = self.data_root
        if root is None or not (Path(root) / "new_joints").is_dir():
            where = f"{root} has no new_joints/ folder" if root else "no folder given"
            raise DatasetError(f"{self.name}: {where}; expected {LAYOUT}; pass --data-root DIR "
                               f"or set {self.env_var}")
        files = sorted((Path(root) / "new_joints").glob("*.npy"))
        if not files:
            raise DatasetError(f"no .npy files in {Path(root) / 'new_joints'}; expected {LAYOUT}")
        return files

    def load_takes(self, subjects=None, actions=None) -> LoadReport:
        """Return one take per whole-clip file and per spanned caption, with captions."""
        self.check_subjects(subjects)
        self.check_actions(actions)
        report = LoadReport()
        for path in self.files():
            try:
                report.motions.extend(self._takes(path))
            except (FormatError, ValueError) as exc:
                report.problems.append(str(exc))
        if not report.motions:
            raise DatasetError(f"no readable clip in {self.data_root}: "
                               f"{'; '.join(report.problems[:3])}")
        return report

    def _takes(self, path: Path) -> list[Motion]:
        joints = read_npy(path, f"joints (T, {self.n_joints}, 3)")
        if joints.ndim != 3 or joints.shape[1:] != (self.n_joints, 3) or not len(joints):
            raise FormatError(f"{path}: joints of shape {joints.shape}; expected "
                              f"(T, {self.n_joints}, 3)")
        text_file = Path(self.data_root) / "texts" / f"{path.stem}.txt"
        captions = read_captions(text_file) if text_file.is_file() else []
        whole = [c for c in captions if c.whole] or ([] if captions else [None])
        meta = {"dataset": self.name, "subject": None, "take": path.stem,
                "captions": [c.text for c in whole if c is not None]}
        takes = [Motion(joints, self.skeleton, self.fps, UNKNOWN_ACTION, meta=meta,
                        text=caption_of([c for c in whole if c is not None]))]
        for caption in captions:
            if caption.whole:
                continue
            start, end = int(caption.start * self.fps), int(caption.end * self.fps)
            if end - start < 2 or end > len(joints):
                continue  # HumanML3D's loader drops spans this short or past the end too
            part = {"dataset": self.name, "subject": None, "take": f"{path.stem}@{start}",
                    "captions": [caption.text], "span": (caption.start, caption.end)}
            takes.append(Motion(joints[start:end], self.skeleton, self.fps, UNKNOWN_ACTION,
                                meta=part, text=caption.text))
        if not whole[0] and len(takes) > 1:
            takes = takes[1:]  # every caption has a span: the whole file has none
        return takes

    def prompts(self) -> list[str]:
        """Return every caption of the dataset, once each, in file order."""
        seen = {}
        for take in self.load_takes().motions:
            for caption in take.meta["captions"]:
                seen.setdefault(normalise(caption), caption)
        return list(seen.values())

    def takes_for(self, prompt: str) -> list[Motion]:
        """Return the takes with this caption (ignoring case and spacing), texts set to it."""
        wanted = normalise(prompt)
        return [take.with_joints(take.joints, text=caption, meta=dict(take.meta))
                for take in self.load_takes().motions for caption in take.meta["captions"]
                if normalise(caption) == wanted]


@register_dataset("kit_ml")
class KitML(HumanML3D):
    """KIT-ML in HumanML3D's layout: 21 joints in millimetres, y up, 12.5 fps."""

    skeleton = "kit21"
    fps = 12.5
    clip_frames = 40
    clip_fps = 12.5
    env_var = "STUDY_KITML_ROOT"
    n_joints = 21

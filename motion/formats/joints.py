"""Folders of joint arrays, as text-to-motion codebases write them.

MoMask (``joints/<k>/sample<k>_repeat<r>_len<L>.npy``), T2M-GPT, MotionGPT and
MotionDiffuse save each generated motion as an ``.npy`` of joint positions ``(T, J, 3)``
(T2M-GPT: ``(1, T, J, 3)``; ``(N, T, J, 3)`` is read as N motions), in HumanML3D's
frame: 22 joints (``smpl22``, y up, metres) or, for KIT-ML models, 21 (``kit21``,
millimetres); ``skeleton`` names another. The files hold no frame rate: ``file_fps``
defaults to 20 (KIT-ML 12.5), the rate these models generate at.

Prompts come from ``texts`` (a file), else a ``prompts.txt``/``prompts.csv`` beside the
files: one line per file in name order, line ``k + 1`` for files named ``sample<k>...``
(MoMask's repeats share their prompt), or a CSV with ``file`` and ``text`` columns;
else from a ``<name>.txt`` beside each file (its first line), else from the file's name
when it spells one (T2M-GPT's and MotionGPT's demos save ``a_person_is_boxing.npy``:
"a person is boxing"). See :func:`motion.formats.base.read_prompts`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from motion.formats.base import (
    MotionList,
    check_finite,
    check_shape,
    files_in,
    format_module,
    load_each,
    prompt_file_beside,
    prompt_from_name,
    prompts_for,
    read_npy,
    read_prompts,
    skeleton_for,
)
from motion.motion import UNKNOWN_ACTION, Motion

SKELETONS = {22: "smpl22", 21: "kit21"}
FPS = {"kit21": 12.5}
LAYOUT = "(T, J, 3) joint positions (or (N, T, J, 3)), e.g. (T, 22, 3) for HumanML3D models"
SOURCE = "imported"


def load(path: str | Path, skeleton: str | None = None, texts: str | Path | None = None,
         file_fps: float | None = None, action: str | None = None,
         source: str = SOURCE) -> list[Motion]:
    """Read joint arrays and their prompts (see the module docstring)."""
    path = Path(path)
    files = [f for f in files_in(path, ("*.npy",), f".npy files of {LAYOUT}")
             if f.stem not in ("Mean", "Std")]
    prompt_file = Path(texts) if texts else prompt_file_beside(files, path)
    if prompt_file is not None:
        prompts = prompts_for(files, read_prompts(prompt_file), prompt_file)
    else:
        prompts = [_own_prompt(f) for f in files]
    by_file = dict(zip(files, prompts))

    def one(file: Path) -> MotionList:
        array = check_shape(read_npy(file, LAYOUT), lambda s: len(s) in (3, 4) and s[-1] == 3
                            and min(s) > 0, file, "joints", LAYOUT)
        check_finite(array, file, "joints")
        batch = array.reshape((-1,) + array.shape[-3:])
        name = skeleton_for(batch.shape[2], skeleton, file, array.shape, SKELETONS)
        fps = file_fps or FPS.get(name, 20.0)
        return MotionList(
            Motion(clip.astype(np.float32), name, fps, action or UNKNOWN_ACTION, source,
                   meta={"file": str(file), **({"index": i} if len(batch) > 1 else {})},
                   text=by_file[file])
            for i, clip in enumerate(batch)
        )

    return load_each(files, one, "joints file")


def _own_prompt(file: Path) -> str | None:
    """Return the first line of ``<name>.txt`` beside a file, else the prompt its name
    spells (``a_person_is_boxing.npy``), if any."""
    beside = file.with_suffix(".txt")
    if not beside.is_file():
        return prompt_from_name(file.stem)
    lines = [line.split("#", 1)[0].strip() for line in beside.read_text(
        encoding="utf-8", errors="replace").splitlines() if line.strip()]
    return lines[0] if lines else None


def detect(probe) -> str | None:
    """Recognise an ``.npy`` of joint positions ``(T, J, 3)`` or ``(1, T, J, 3)``."""
    shape = probe.shape
    if shape is None or probe.options.get("classes_path") or shape[-1:] != (3,):
        return None
    if len(shape) == 3 or (len(shape) == 4 and shape[0] == 1):
        return f"an array of shape {shape}: joint positions (T, J, 3)"
    return None


format_module(__name__)

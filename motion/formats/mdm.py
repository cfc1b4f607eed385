"""motion-diffusion-model (MDM) outputs: ``results.npy`` and ``*_smpl_params.npy``.

``sample/generate.py`` writes ``results.npy``, an ``np.save`` of a dict:

- ``motion``: ``(N, J, 3, T)`` float joint positions; ``J`` = 22 (HumanML3D, ``smpl22``,
  20 fps), 21 (KIT-ML, ``kit21``, millimetres, 12.5 fps) or 24 (its action models,
  SMPL's joints, ``smpl24``, 20 fps; these are y down and turned upright on import);
- ``text``: N prompts (action models: their action names; also read from ``action_text``
  or ``action``); a list of prompts (DiP's dynamic prompts) is joined with " / ";
- ``lengths``: ``(N,)`` frames of each motion (the rest of ``T`` is cut off);
- ``num_samples``, ``num_repetitions``: motion ``i`` is sample ``i % num_samples`` of
  repetition ``i // num_samples``.

``visualize/render_mesh.py`` writes ``sample<i>_rep<r>_smpl_params.npy`` beside it: a
dict with ``motion`` ``(25, 6, T)``, ``thetas``, ``root_translation`` ``(3, T)``,
``vertices`` ``(6890, 3, T)``, ``faces`` ``(13776, 3)``, ``text`` and ``length``. Its
joints are those of the same motion in ``results.npy`` beside it (its own ``text`` is
always the first sample's, so the prompt is taken from there too), else regressed from
the vertices with the user's SMPL model (``body_models``); the mesh keeps its vertices,
moved onto the joints.

Text-conditioned motions get ``text`` = their prompt and ``action`` = ``action`` (default
``unknown``); action-conditioned ones ``action`` = their action name.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from motion.body_models import BodyModelError, load_body_model
from motion.formats.base import (
    FormatError,
    MotionList,
    check_lengths,
    check_shape,
    files_in,
    finite_only,
    format_module,
    load_each,
    need_keys,
    pickled_dict,
    read_npy,
    skeleton_for,
)
from motion.formats.smpl_poses import stand_upright
from motion.motion import UNKNOWN_ACTION, Motion

SOURCE = "mdm"
SKELETONS = {22: "smpl22", 21: "kit21", 24: "smpl24"}
FPS = {"smpl22": 20.0, "kit21": 12.5, "smpl24": 20.0}
RESULTS_LAYOUT = ("MDM's results.npy: a dict with motion (N, J, 3, T), text (N prompts), "
                  "lengths (N,), num_samples, num_repetitions")
PARAMS_LAYOUT = ("MDM's *_smpl_params.npy: a dict with motion (25, 6, T), vertices "
                 "(6890, 3, T), faces (F, 3), text, length")
_PARAMS_NAME = re.compile(r"sample(\d+)_rep(\d+)_smpl_params$")


def load(path: str | Path, skeleton: str | None = None, action: str | None = None,
         file_fps: float | None = None, body_models: str | Path | None = None,
         source: str = SOURCE) -> list[Motion]:
    """Read ``results.npy``, a ``*_smpl_params.npy``, or a folder of either (see module doc).

    A folder gives its ``results.npy`` files, or, when it has none, its mesh files.
    """
    path = Path(path)
    options = dict(skeleton=skeleton, action=action, file_fps=file_fps,
                   body_models=body_models, source=source)
    if path.is_dir():
        results = [f for f in files_in(path, ("*.npy",), "MDM outputs") if f.name == "results.npy"]
        files = results or files_in(path, ("*_smpl_params.npy",), "MDM outputs")
        return load_each(files, lambda file: load(file, **options), "MDM file")
    if path.name.endswith("_smpl_params.npy"):
        return load_params(path, **options)
    return load_results(path, **{k: v for k, v in options.items() if k != "body_models"})


def read_results(path: Path) -> dict:
    """Return the dict of a ``results.npy``, checked for its keys."""
    data = pickled_dict(read_npy(path, "MDM results", objects=True), path, RESULTS_LAYOUT)
    need_keys(data, ("motion",), path, RESULTS_LAYOUT)
    if not any(key in data for key in ("text", "action_text", "action")):
        raise FormatError(f"{path}: no key 'text' (nor 'action_text', 'action'); expected "
                          f"{RESULTS_LAYOUT}")
    return data


def load_results(path: Path, skeleton=None, action=None, file_fps=None,
                 source: str = SOURCE) -> MotionList:
    """Read MDM's ``results.npy``."""
    data = read_results(path)
    motion = check_shape(data["motion"], lambda s: len(s) == 4 and s[2] == 3 and min(s) > 0,
                         path, "motion", "(N, J, 3, T): N motions of J joints, x y z, T frames")
    count, n_joints, _, frames = motion.shape
    name = skeleton_for(n_joints, skeleton, path, motion.shape, SKELETONS)
    texts = _texts(data, count, path)
    lengths = check_lengths(data.get("lengths", np.full(count, frames)), frames, count, path)
    samples = int(data.get("num_samples", count) or count)
    joints = motion.transpose(0, 3, 1, 2).astype(np.float32)  # (N, T, J, 3)
    action_model = n_joints == 24
    motions = []
    for i in range(count):
        clip = joints[i, : lengths[i]]
        if action_model:
            clip = stand_upright(clip)[0]
        meta = {"file": str(path), "index": i, "sample": i % samples,
                "repetition": i // samples}
        if action_model:
            motions.append(Motion(clip, name, file_fps or FPS.get(name, 20.0),
                                  action or texts[i] or UNKNOWN_ACTION, source, meta=meta))
        else:
            motions.append(Motion(clip, name, file_fps or FPS.get(name, 20.0),
                                  action or UNKNOWN_ACTION, source, meta=meta, text=texts[i]))
    return finite_only(motions, path)


def _texts(data: dict, count: int, path: Path) -> list[str | None]:
    key = next(k for k in ("text", "action_text", "action") if k in data)
    values = list(np.asarray(data[key], dtype=object).reshape(-1)) if not isinstance(
        data[key], (list, tuple)) else list(data[key])
    if len(values) != count:
        raise FormatError(f"{path}: {key} has {len(values)} entries for {count} motions; "
                          "expected one prompt per motion")
    texts = []
    for value in values:
        if isinstance(value, (list, tuple, np.ndarray)):
            value = " / ".join(str(v) for v in value)
        value = str(value).strip()
        texts.append(None if value in ("", "unconstrained") else value)
    return texts


def load_params(path: Path, skeleton=None, action=None, file_fps=None, body_models=None,
                source: str = SOURCE) -> MotionList:
    """Read one ``*_smpl_params.npy`` (one motion with its SMPL mesh)."""
    data = pickled_dict(read_npy(path, "MDM SMPL parameters", objects=True), path,
                        PARAMS_LAYOUT)
    need_keys(data, ("vertices", "faces"), path, PARAMS_LAYOUT)
    vertices = check_shape(data["vertices"], lambda s: len(s) == 3 and s[1] == 3 and s[2] > 0,
                           path, "vertices", "(V, 3, T)").transpose(2, 0, 1).astype(np.float32)
    faces = check_shape(data["faces"], lambda s: len(s) == 2 and s[1] == 3, path, "faces",
                        "(F, 3) vertex indices")
    if skeleton not in (None, "smpl22"):
        raise FormatError(f"{path}: MDM meshes come with smpl22 joints; got skeleton {skeleton!r}")
    length = int(data.get("length", len(vertices)))
    check_lengths([length], len(vertices), 1, path, "length")
    vertices = vertices[:length]
    text = str(data.get("text") or "").strip() or None
    joints, vertices, text = _params_joints(path, vertices, length, text, body_models)
    motion = Motion(joints, "smpl22", file_fps or 20.0, action or UNKNOWN_ACTION, source,
                    meta={"file": str(path)}, text=text, vertices=vertices,
                    faces=faces.astype(np.int64))
    return finite_only([motion], path)


def _params_joints(path: Path, vertices: np.ndarray, length: int, text, body_models):
    """Return the joints ``(T, 22, 3)`` of a mesh file, its vertices (moved onto them) and
    its prompt (see the module docstring)."""
    results = path.parent / "results.npy"
    match = _PARAMS_NAME.search(path.stem)
    if results.is_file() and match:
        data = read_results(results)
        samples = int(data.get("num_samples", 1) or 1)
        index = int(match.group(2)) * samples + int(match.group(1))
        motion = np.asarray(data["motion"])
        if motion.ndim != 4 or index >= len(motion) or motion.shape[1] != 22:
            raise FormatError(f"{results}: motion of shape {motion.shape} has no 22-joint "
                              f"motion {index} for {path.name}")
        joints = motion[index].transpose(2, 0, 1)[:length].astype(np.float32)
        if len(joints) != length:
            raise FormatError(f"{path}: length {length}, but motion {index} of {results} has "
                              f"{len(joints)} frames")
        text = _texts(data, len(motion), results)[index] or text
        # The mesh was posed at the origin: move it onto the joints as a whole.
        vertices = vertices + (joints.mean(axis=(0, 1)) - vertices.mean(axis=(0, 1)))
        return joints, vertices, text
    try:
        model = load_body_model("smpl", "neutral", body_models)
    except BodyModelError as exc:
        raise FormatError(f"{path}: its joints are in results.npy beside it (not found), or "
                          f"come from the SMPL model: {exc}") from None
    return model.regress(vertices)[:, :22], vertices, text


def detect(probe) -> str | None:
    """Recognise MDM's ``results.npy`` (motion and text) and ``*_smpl_params.npy``."""
    if probe.suffix != ".npy" or probe.shape is not None:
        return None
    content = probe.content
    if isinstance(content, dict) and {"vertices", "faces"} <= set(content):
        return "a dict with vertices and faces (MDM's *_smpl_params.npy)"
    if isinstance(content, dict) and "motion" in content:
        return "a dict with motion and text (MDM's results.npy)"
    return None


format_module(__name__)

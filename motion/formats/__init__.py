"""Motion file formats, one module each with ``load``; :func:`load_motions` reads any.

Every format is a module of this package that registers itself at its end
(``format_module(__name__)``), found by the registry's discovery (:func:`list_formats`
is the authoritative list; a module may declare the file endings it reads, ``SUFFIXES``);
``get_format(name).load(path, **options)`` returns the motions of a file or folder. The
options of each format are its ``load``'s keyword arguments:

- ``npz``: the interchange file (README, "Interchange format"); ``skeleton`` (checked);
- ``a2m``: Action2Motion's joints and class-index ``.npy``; ``classes_path`` (required),
  ``skeleton``, ``file_fps``, ``action_names``;
- ``bvh``: BVH files, one motion each, as their own skeleton or mapped onto ``skeleton``;
  ``action``, ``mapping``, ``scale``, ``up``, ``texts``;
- ``mdm``: motion-diffusion-model's ``results.npy`` and ``*_smpl_params.npy``;
- ``humanml3d``, ``humanml3d_vec``: HumanML3D's ``new_joints`` and ``new_joint_vecs``;
- ``joints``: ``.npy`` joint arrays (MoMask, T2M-GPT, MotionGPT, MotionDiffuse);
- ``amass``: AMASS ``.npz`` pose parameters, through SMPL body models the user supplies;
- ``smplx``: SMPL-X poses (BEAT2/EMAGE and AMASS SMPL-X ``.npz``, Motion-X ``.npy``), through
  the user's SMPL-X model; ``hands`` keeps the finger joints;
- ``motioncritic``: MotionCritic's ``.npz`` (rot6d SMPL parameters, 4 per file);
- ``actor``: ACTOR's ``generation.npy`` of SMPL vertices;
- pose estimators, through the user's SMPL model, stood upright on the floor: ``wham``
  (``person``, ``frame`` world or camera), ``phalp`` (4D-Humans; ``person``), ``vibe``
  (``person``), ``tram``;
- datasets and simulators: ``aistpp`` (AIST++ SMPL), ``phc`` (PHC motion libraries, z
  up), ``amp_poselib`` (IsaacGym AMP's ``SkeletonMotion`` ``.npy``, its own skeleton);
- ``auto``: any of these, detected from the content (every format's ``detect``).
"""

from __future__ import annotations

import inspect
from pathlib import Path

from motion import ops
from motion.formats.base import (
    FormatError,
    MotionList,
    get_format,
    list_formats,
    register_format,
)
from motion.motion import Motion


def format_options(format: str) -> list[str]:
    """Return the option names a format's ``load`` takes (``auto``: every format's)."""
    parameters = list(inspect.signature(get_format(format).load).parameters.values())[1:]
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return sorted({name for other in list_formats() if other != format
                       for name in format_options(other)})
    return [p.name for p in parameters]


def load_motions(path: str | Path, format: str, fps: float | None = None,
                 source: str | None = None, **options) -> list[Motion]:
    """Read the motions of a file or folder of any format; ``fps`` resamples, ``source``
    relabels. ``options`` go to the format (see the module docstring).

    The result is a :class:`MotionList`: its ``problems`` name the files (or motions)
    that could not be read, its ``notes`` what was found.
    """
    loader = get_format(format)
    accepted = format_options(format)
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        raise FormatError(f"format {format!r} takes options {', '.join(accepted)}; "
                          f"got {', '.join(unknown)}")
    loaded = loader.load(path, **options)
    result = MotionList(problems=getattr(loaded, "problems", ()),
                        notes=getattr(loaded, "notes", ()))
    for motion in loaded:
        if fps:
            motion = ops.resample(motion, fps)
        if source:
            motion = motion.with_joints(motion.joints, source=source, meta=dict(motion.meta))
        result.append(motion)
    return result


__all__ = ["FormatError", "MotionList", "format_options", "get_format", "list_formats",
           "load_motions", "register_format"]

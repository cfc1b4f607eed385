"""Train a method on a registered dataset and checkpoint it: what ``manage.py train`` runs.

The config is the preset's under a schedule (:mod:`generation.methods.schedule`): ``full``
(the preset's phases, refusing a budget that ends inside the first) or ``benchmark`` (the
first phase takes its share of the budget, as ``compare_methods`` trains it).
"""

from __future__ import annotations

from pathlib import Path

from motion.datasets import DatasetError, get_dataset
from generation.methods.base import Method, MethodError
from generation.methods import get_method
from generation.methods.schedule import check_changes, recipe_for
from generation.sampling import choose, choose_subjects


def train_on_dataset(method: str, dataset: str, out: str | Path, *, data_root=None,
                     subjects=None, actions=None, iters: int = 1000, preset: str = "paper",
                     seed: int = 0, frames: int | None = None, fps: float | None = None,
                     resume: bool = False, progress: bool = True,
                     save_every: int = 500, schedule: str = "full",
                     changes: dict | None = None) -> Method:
    """Train ``method`` on clips of ``dataset`` up to ``iters`` iterations in all; save to ``out``.

    With ``resume`` and an existing ``out``, training continues from that checkpoint
    (its config, actions, frames and fps win). A checkpoint is also written every
    ``save_every`` iterations, so an interrupted run can resume. ``schedule`` is how the
    preset's first phase meets the budget (:func:`generation.methods.schedule.recipe_for`);
    ``changes`` set config fields of the preset (e.g. sa_gcn's ``{"init": "he"}``), saved
    with the checkpoint's config.
    """
    cls = get_method(method)
    data = get_dataset(dataset, data_root)
    out = Path(out)
    subjects = choose_subjects(data, subjects)
    if resume and out.exists():
        model = cls.load(out, skeleton=data.skeleton)
        wanted = choose(actions, model.actions, "action", f"checkpoint {out}") if actions else model.actions
        if wanted != model.actions:
            raise MethodError(
                f"checkpoint {out} was trained on actions {', '.join(model.actions)}; "
                f"resume with those (drop --actions) or start afresh without --resume"
            )
        frames, fps = model.frames, model.fps
    else:
        actions = choose(actions, data.actions(), "action", f"dataset {dataset!r}")
        frames = frames or data.clip_frames
        model = None
    clips = data.clips(frames=frames, fps=fps, subjects=subjects,
                       actions=model.actions if model else actions)
    if not clips:
        raise DatasetError(
            f"dataset {dataset!r} gave no clips of {frames} frames for these actions and "
            f"subjects; check --data-root, --subjects, --actions and --frames"
        )
    if model is None:
        config = recipe_for(method, preset, iters, schedule,
                            check_changes(method, preset, changes)).config(cls)
        model = cls(config, data.skeleton, actions, clips[0].fps, frames)
    model.fit(clips, max(iters - model.iteration, 0), seed=seed, progress=progress,
              save_to=out, save_every=save_every)
    model.save(out)
    return model

"""Draw motion sets from a trained method or from real data, alike: what ``manage.py sample`` runs.

Both give ``n`` motions per action, action by action, ready for
:func:`motion.formats.npz.save`; studies and metrics then treat real data as one
more source.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from motion.motion import Motion

ALL = "all"


class SamplingError(ValueError):
    """A request for motions names an unknown action or subject, or data to draw is missing."""


def split_names(values: str | Iterable[str] | None) -> list[str]:
    """Return the names in comma-separated strings (repeatable options), in order, once each."""
    if values is None:
        return []
    if isinstance(values, str):
        values = [values]
    names: list[str] = []
    for value in values:
        for name in value.split(","):
            name = name.strip()
            if name and name not in names:
                names.append(name)
    return names


def choose(requested: str | Iterable[str] | None, known: Sequence[str], kind: str,
           owner: str) -> list[str]:
    """Return the requested names; ``all`` or nothing means all ``known`` ones.

    Unknown names raise :class:`SamplingError` listing what ``owner`` offers.
    """
    names = split_names(requested)
    if not names or ALL in names:
        return list(known)
    unknown = [name for name in names if name not in known]
    if unknown:
        raise SamplingError(
            f"{owner} has no {kind} {', '.join(map(repr, unknown))}; "
            f"choose from {', '.join(known)} (or {ALL!r})"
        )
    return names


def choose_subjects(dataset, requested: str | Iterable[str] | None) -> list[str] | None:
    """Return the dataset's subjects to use (``None``: all), checked against the dataset."""
    names = split_names(requested)
    if not names:
        return None
    if dataset.subjects is None:
        raise SamplingError(
            f"dataset {dataset.name!r} has no subjects; drop --subjects"
        )
    return choose(names, dataset.subjects, "subject", f"dataset {dataset.name!r}")


def sample_real(dataset, actions: str | Iterable[str] | None, n: int, frames: int | None = None,
                seed: int = 0, fps: float | None = None, subjects=None) -> list[Motion]:
    """Return ``n`` real clips per action, chosen by ``seed`` among the dataset's clips.

    Clips are drawn without replacement while they last, then repeated at random
    (as metrics that sample real motions with replacement need). ``frames`` and ``fps``
    default to the dataset's clip length and rate.
    """
    if n < 1:
        raise SamplingError(f"n must be at least 1; got {n}")
    actions = choose(actions, dataset.actions(), "action", f"dataset {dataset.name!r}")
    subjects = choose_subjects(dataset, subjects)
    clips = dataset.clips(frames=frames, fps=fps, subjects=subjects, actions=actions)
    rng = np.random.default_rng(seed)
    motions = []
    for action in actions:
        pool = [clip for clip in clips if clip.action == action]
        if not pool:
            raise SamplingError(
                f"dataset {dataset.name!r} has no clips of {action!r}"
                f"{' for subjects ' + ','.join(subjects) if subjects else ''} "
                f"of {frames or dataset.clip_frames} frames; pick other actions or subjects, "
                f"or shorter clips"
            )
        order = rng.permutation(len(pool))
        if n > len(pool):
            order = np.concatenate([order, rng.integers(len(pool), size=n - len(pool))])
        motions.extend(pool[i] for i in order[:n])
    return motions


def sample_method(checkpoint: str | Path, actions: str | Iterable[str] | None, n: int,
                  frames: int | None = None, seed: int = 0, method: str | None = None,
                  **options) -> list[Motion]:
    """Return ``n`` motions per action from the method saved at ``checkpoint``.

    With ``method``, the checkpoint must be of that method. ``options`` go to the
    method's ``sample`` (e.g. ``bone_lengths`` for ``a2m``).
    """
    from generation.methods import get_method, load_checkpoint

    if n < 1:
        raise SamplingError(f"n must be at least 1; got {n}")
    model = get_method(method).load(checkpoint) if method else load_checkpoint(checkpoint)
    actions = choose(actions, model.actions, "action", f"{model.name} checkpoint {checkpoint}")
    return model.sample([action for action in actions for _ in range(n)], frames=frames, seed=seed,
                        **options)


def sample_checkpoints(checkpoints: Sequence[str | Path], actions: Sequence[str], n: int,
                       frames: int | None = None, seed: int = 0,
                       method: str | None = None) -> list[Motion]:
    """Return ``n`` motions in all from the methods saved at ``checkpoints`` (a source's
    checkpoints, one per training seed), spread as evenly as can be over ``actions`` and,
    within an action, over the checkpoints in turn: a fresh sample of the source, e.g. for
    its objective metrics."""
    if n < 1:
        raise SamplingError(f"n must be at least 1; got {n}")
    if not checkpoints or not actions:
        raise SamplingError("give at least one checkpoint and one action")
    per_action = [len(range(a, n, len(actions))) for a in range(len(actions))]
    wanted = {}  # checkpoint index -> actions, one entry per motion
    for a, count in enumerate(per_action):
        for i in range(count):
            wanted.setdefault(i % len(checkpoints), []).append(actions[a])
    from generation.methods import get_method, load_checkpoint

    motions = []
    for k, labels in sorted(wanted.items()):
        path = checkpoints[k]
        model = get_method(method).load(path) if method else load_checkpoint(path)
        choose(sorted(set(labels)), model.actions, "action", f"{model.name} checkpoint {path}")
        motions += model.sample(labels, frames=frames, seed=seed)
    return motions

"""Which clips a classifier (and the metrics measured with it) hold out: subjects or takes."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Sequence

import numpy as np

from motion.motion import Motion
from motion_metrics.recognition.errors import ClassifierError
from generation.sampling import choose_subjects, split_names

TEST_FRACTION = 0.2  # held-out share of subjects, or of takes without subjects
VALIDATION_FRACTION = 0.2  # share of each action's training takes that validates


@dataclass(frozen=True)
class Split:
    """Which clips of a dataset are held out: whole subjects, or whole takes when it has none.

    ``train_subjects`` ``None`` means every subject not held out.
    """

    test_subjects: tuple[str, ...] | None = None
    train_subjects: tuple[str, ...] | None = None
    test_takes: tuple[str, ...] | None = None

    def is_test(self, clip: Motion) -> bool:
        if self.test_subjects is not None:
            return clip.meta.get("subject") in self.test_subjects
        return _take_key(clip) in (self.test_takes or ())

    def is_train(self, clip: Motion) -> bool:
        if self.is_test(clip):
            return False
        return self.train_subjects is None or clip.meta.get("subject") in self.train_subjects

    def divide(self, clips: Sequence[Motion]) -> tuple[list[Motion], list[Motion]]:
        """Return the training clips and the held-out clips."""
        return [c for c in clips if self.is_train(c)], [c for c in clips if self.is_test(c)]

    def describe(self) -> str:
        if self.test_subjects is not None:
            return f"held-out subjects {', '.join(self.test_subjects)}"
        return f"{len(self.test_takes or ())} held-out takes"

    def to_dict(self) -> dict:
        return {key: None if value is None else list(value) for key, value in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> "Split":
        return cls(**{key: None if values.get(key) is None else tuple(values[key])
                      for key in ("test_subjects", "train_subjects", "test_takes")})


def _take_key(clip: Motion) -> str:
    return f"{clip.action}/{clip.meta.get('subject')}/{clip.meta.get('take')}"


def make_split(dataset, clips: Sequence[Motion], test_subjects=None, subjects=None,
               seed: int = 0) -> Split:
    """Return the held-out split of ``clips`` of ``dataset``.

    With subjects: ``test_subjects`` (default: the last fifth of the dataset's subjects,
    at least one; for Human3.6M S9 and S11, the usual protocol) are held out and
    ``subjects`` (default: the others) train. Without: a seeded fifth of each action's
    takes (at least one when it has two or more), so no take feeds both sides.
    """
    if dataset.subjects is not None:
        last = math.ceil(TEST_FRACTION * len(dataset.subjects))
        test = choose_subjects(dataset, test_subjects) or list(dataset.subjects[-last:])
        train = choose_subjects(dataset, subjects)
        overlap = sorted(set(train or ()) & set(test))
        if overlap:
            raise ClassifierError(
                f"subjects {', '.join(overlap)} are both trained on and held out; "
                f"--subjects and --test-subjects must not overlap"
            )
        return Split(test_subjects=tuple(test), train_subjects=None if train is None else tuple(train))
    if split_names(test_subjects) or split_names(subjects):
        raise ClassifierError(
            f"dataset {dataset.name!r} has no subjects; drop --subjects and --test-subjects "
            f"(a seeded {TEST_FRACTION:.0%} of its takes is held out)"
        )
    return Split(test_takes=tuple(_hold_out_takes(clips, TEST_FRACTION, seed)))


def _hold_out_takes(clips: Sequence[Motion], fraction: float, seed: int) -> list[str]:
    """Return a seeded ``fraction`` of each action's takes (at least one of two or more)."""
    rng = np.random.default_rng(seed)
    held_out = []
    for action in sorted({clip.action for clip in clips}):
        takes = sorted({_take_key(clip) for clip in clips if clip.action == action})
        count = max(1, round(fraction * len(takes))) if len(takes) > 1 else 0
        held_out.extend(takes[i] for i in sorted(rng.choice(len(takes), size=count, replace=False)))
    return held_out


def validation_split(clips: Sequence[Motion], fraction: float = VALIDATION_FRACTION,
                     seed: int = 0) -> tuple[list[Motion], list[Motion]]:
    """Divide training clips into clips to fit and clips to validate on, by whole takes.

    A seeded ``fraction`` of each action's takes validates (at least one when the action
    has two or more), so no take feeds both sides.
    """
    if not 0 < fraction < 1:
        raise ClassifierError(f"the validation share must be between 0 and 1; got {fraction!r}")
    held = set(_hold_out_takes(clips, fraction, seed + 1))
    return ([c for c in clips if _take_key(c) not in held], [c for c in clips if _take_key(c) in held])

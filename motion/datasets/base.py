"""The dataset interface and its registry."""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

from motion import ops
from motion.motion import Motion
from motion.registry import Registry

DATASETS = Registry("dataset", package="motion.datasets")
register_dataset = DATASETS.register

logger = logging.getLogger(__name__)


class DatasetError(ValueError):
    """Data is missing or malformed; the message names the path and the layout expected."""


@dataclass
class LoadReport:
    """What a load found: good motions, and one line per file that could not be read."""

    motions: list[Motion] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


class Dataset:
    """A source of real motions, read from ``data_root`` (or made, for ``demo``).

    Subclasses set the class attributes and implement :meth:`load_takes` and
    :meth:`actions`; :meth:`clips` cuts the takes into fixed-length clips. Every motion's
    ``meta`` names its ``dataset``, ``subject`` (``None`` without subjects) and ``take``;
    clips add ``start_frame`` (first frame, counted at the clip frame rate) and
    ``start_time`` (seconds from the start of the take).
    """

    name: str = ""
    skeleton: str = ""
    fps: float = 25.0  # native frame rate of the takes
    clip_frames: int = 60  # default clip length for training and studies
    clip_fps: float = 25.0  # default clip frame rate
    subjects: tuple[str, ...] | None = None  # None: the dataset has no subjects
    synthetic: bool = False
    env_var: str | None = None  # environment variable overriding the default root
    default_dir: str | None = None  # default root, relative to the project folder

    def __init__(self, data_root: str | Path | None = None):
        self.data_root = Path(data_root) if data_root else self.default_root()

    @classmethod
    def default_root(cls) -> Path | None:
        """Return the root from the environment variable, else the default folder."""
        if cls.env_var and os.environ.get(cls.env_var):
            return Path(os.environ[cls.env_var])
        if cls.default_dir:
            return (Path(__file__).resolve().parents[2] / cls.default_dir).resolve()
        return None

    def load_takes(self, subjects=None, actions=None) -> LoadReport:
        """Return whole takes at the native frame rate, and the problems met."""
        raise NotImplementedError

    def actions(self) -> list[str]:
        """Return the action names, in class-index order."""
        raise NotImplementedError

    def known_actions(self) -> list[str]:
        """Return every action name a caller may ask for (default: :meth:`actions`)."""
        return self.actions()

    def take_lengths(self, subjects=None, actions=None) -> list[int]:
        """Return the number of native frames of each take (subclasses may skip loading)."""
        return [take.frames for take in self.load_takes(subjects, actions).motions]

    def clips(self, frames=None, fps=None, subjects=None, actions=None, stride=None,
              max_per_take=None) -> list[Motion]:
        """Return fixed-length clips (default ``clip_frames`` at ``clip_fps``).

        Each take is resampled to ``fps``, then cut into windows of ``frames`` frames
        every ``stride`` frames (default ``frames // 2``), at most ``max_per_take`` per
        take, evenly spread. The order is that of the takes, then of time.
        """
        frames = frames or self.clip_frames
        fps = fps or self.clip_fps
        report = self.load_takes(subjects=subjects, actions=actions)
        for problem in report.problems:
            logger.warning("%s: %s", self.name, problem)
        clips = []
        for take in report.motions:
            resampled = ops.resample(take, fps)
            for clip in ops.windows(resampled, frames, stride, max_per_take):
                clip.meta["start_time"] = clip.meta["start_frame"] / fps
                clips.append(clip)
        return clips

    def count_clips(self, frames=None, fps=None, subjects=None, actions=None, stride=None,
                    max_per_take=None) -> int:
        """Return how many clips :meth:`clips` gives for the same arguments."""
        frames = frames or self.clip_frames
        fps = fps or self.clip_fps
        return sum(
            len(ops.window_starts(ops.resampled_length(length, self.fps, fps), frames,
                                  stride, max_per_take))
            for length in self.take_lengths(subjects=subjects, actions=actions)
        )

    def check_subjects(self, subjects) -> list[str] | None:
        """Return the requested subjects in canonical spelling, or ``None`` for all."""
        if subjects is None:
            return None
        if self.subjects is None:
            raise DatasetError(f"dataset {self.name!r} has no subjects; do not pass subjects")
        return _canonical("subject", self.name, subjects, self.subjects)

    def check_actions(self, actions) -> list[str]:
        """Return the requested actions in canonical spelling (default: :meth:`actions`)."""
        if actions is None:
            return list(self.actions())
        return _canonical("action", self.name, actions, self.known_actions())


def _canonical(kind: str, dataset: str, requested, valid) -> list[str]:
    """Match names case-insensitively against the valid ones, or raise listing them."""
    if isinstance(requested, str):
        requested = [requested]
    lookup = {name.lower(): name for name in valid}
    unknown = [name for name in requested if str(name).lower() not in lookup]
    if unknown:
        raise DatasetError(
            f"unknown {kind}{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))} "
            f"for dataset {dataset!r}; valid {kind}s: {', '.join(valid)}"
        )
    return [lookup[str(name).lower()] for name in requested]


def get_dataset(name: str, data_root: str | Path | None = None) -> Dataset:
    """Return a dataset instance by registry name."""
    return DATASETS.get(name)(data_root)


def list_datasets() -> list[str]:
    """Return the names of all registered datasets."""
    return DATASETS.names()

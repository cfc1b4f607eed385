"""Operations on motions: free functions that return new motions."""

from __future__ import annotations

import numpy as np

from generation.motion import Motion, MotionError

# Frame counts derived from fps ratios such as 25 -> 50/3 land a hair below an integer.
_EPS = 1e-6


def resampled_length(frames: int, fps_from: float, fps_to: float) -> int:
    """Return how many frames :func:`resample` makes of ``frames`` frames."""
    if frames < 1:
        return 0
    return int(np.floor((frames - 1) * fps_to / fps_from + _EPS)) + 1


def resample(motion: Motion, fps: float) -> Motion:
    """Return the motion at another frame rate, by linear interpolation in time.

    The first frame is kept; the last new frame is the last one at or before the
    motion's end. ``joints`` ``(T, J, D)`` becomes ``(T', J, D)`` with
    ``T' = resampled_length(T, motion.fps, fps)``.
    """
    if fps <= 0:
        raise MotionError(f"fps must be positive; got {fps!r}")
    if abs(fps - motion.fps) < _EPS or motion.frames < 2:
        return motion.with_joints(motion.joints, fps=fps, meta=dict(motion.meta))
    frames = resampled_length(motion.frames, motion.fps, fps)
    source = np.arange(frames) * (motion.fps / fps)
    source = np.minimum(source, motion.frames - 1)
    lower = np.minimum(np.floor(source + _EPS).astype(int), motion.frames - 2)
    weight = np.clip(source - lower, 0.0, 1.0)[:, None, None].astype(np.float32)
    joints = motion.joints[lower] * (1 - weight) + motion.joints[lower + 1] * weight
    return motion.with_joints(joints, fps=fps, meta=dict(motion.meta))


def trim(motion: Motion, start: int, frames: int) -> Motion:
    """Return ``frames`` frames from ``start`` (both in frames of the motion)."""
    if start < 0 or frames < 1 or start + frames > motion.frames:
        raise MotionError(
            f"cannot cut frames {start}..{start + frames} from a motion of "
            f"{motion.frames} frames"
        )
    return motion.with_joints(motion.joints[start:start + frames], meta=dict(motion.meta))


def window_starts(length: int, frames: int, stride: int | None = None,
                  max_count: int | None = None) -> list[int]:
    """Return the first frames of the windows of ``frames`` frames in ``length`` frames.

    Windows start every ``stride`` frames (default ``frames // 2``); with ``max_count``
    at most that many are kept, evenly spread over the take (one window: the middle).
    """
    if frames < 1:
        raise MotionError(f"a window needs at least one frame; got {frames}")
    stride = stride or max(frames // 2, 1)
    if stride < 1:
        raise MotionError(f"stride must be at least one frame; got {stride}")
    starts = list(range(0, length - frames + 1, stride))
    if max_count is not None and len(starts) > max_count:
        # The centre of each of max_count equal shares of the windows.
        picks = ((np.arange(max_count) + 0.5) * len(starts) / max_count).astype(int)
        starts = [starts[i] for i in picks]
    return starts


def windows(motion: Motion, frames: int, stride: int | None = None,
            max_count: int | None = None) -> list[Motion]:
    """Cut fixed-length windows; each one's ``meta["start_frame"]`` is its first frame.

    See :func:`window_starts` for ``stride`` and ``max_count``. A motion shorter than
    ``frames`` gives no window.
    """
    clips = []
    for start in window_starts(motion.frames, frames, stride, max_count):
        clip = trim(motion, start, frames)
        clip.meta["start_frame"] = start
        clips.append(clip)
    return clips


def select_joints(motion: Motion, joints: tuple[int, ...] | list[int], skeleton: str) -> Motion:
    """Keep some joints (indices into the motion's joints) as a motion of ``skeleton``."""
    return motion.with_joints(motion.joints[:, list(joints)], skeleton=skeleton,
                              meta=dict(motion.meta))

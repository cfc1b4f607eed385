"""Operations on motions: free functions that return new motions."""

from __future__ import annotations

import math

import numpy as np

from motion.motion import Motion, MotionError
from motion.skeletons import canonical_skeleton, flat_skeleton, get_skeleton

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

    def blend(values: np.ndarray) -> np.ndarray:
        return values[lower] * (1 - weight) + values[lower + 1] * weight

    body = {} if motion.vertices is None else {"vertices": blend(motion.vertices)}
    return motion.with_joints(blend(motion.joints), fps=fps, meta=dict(motion.meta), **body)


def trim(motion: Motion, start: int, frames: int) -> Motion:
    """Return ``frames`` frames from ``start`` (both in frames of the motion)."""
    if start < 0 or frames < 1 or start + frames > motion.frames:
        raise MotionError(
            f"cannot cut frames {start}..{start + frames} from a motion of "
            f"{motion.frames} frames"
        )
    body = {} if motion.vertices is None else {"vertices": motion.vertices[start:start + frames]}
    return motion.with_joints(motion.joints[start:start + frames], meta=dict(motion.meta), **body)


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


def axis_rotation(source: str, target: str) -> np.ndarray:
    """Return the rotation ``(3, 3)`` taking axis ``source`` onto ``target``.

    Axes are ``"x"``, ``"y"``, ``"z"``, optionally signed (``"-y"``); the rotation turns
    by 90 degrees about the axis perpendicular to both (y up -> z up: ``(x, y, z) ->
    (x, -z, y)``), by 180 degrees about the first other axis for opposite axes. Every
    rotation is proper, so a left side stays left.
    """
    def unit(axis: str) -> np.ndarray:
        vector = np.zeros(3)
        vector["xyz".index(axis[-1])] = -1.0 if axis.startswith("-") else 1.0
        return vector

    a, b = unit(source), unit(target)
    if np.allclose(a, b):
        return np.eye(3)
    if np.allclose(a, -b):
        flip = np.zeros(3)
        flip[(int(np.argmax(np.abs(a))) + 1) % 3] = 1.0
        return 2.0 * np.outer(flip, flip) - np.eye(3)
    cross = np.cross(a, b)
    skew = np.array([[0, -cross[2], cross[1]], [cross[2], 0, -cross[0]],
                     [-cross[1], cross[0], 0]])
    return np.eye(3) + skew + skew @ skew


def transform(motion: Motion, matrix: np.ndarray, skeleton: str | None = None,
              offset=None) -> Motion:
    """Return the motion with joints and vertices mapped by ``x @ matrix.T + offset``."""
    matrix = np.asarray(matrix, dtype=np.float32)
    shift = np.zeros(matrix.shape[0], np.float32) if offset is None else np.float32(offset)
    body = {}
    if motion.vertices is not None:
        body["vertices"] = motion.vertices @ matrix.T + shift
    return motion.with_joints(motion.joints @ matrix.T + shift, meta=dict(motion.meta),
                              skeleton=skeleton or motion.skeleton, **body)


def canonical(motion: Motion, dims: int = 3, fps: float | None = None) -> Motion:
    """Return the motion in the renderer's frame: z up, metres (and ``fps``, if given).

    This is the one place where a skeleton's up axis and units are applied before
    drawing. The result's skeleton has the same joints with ``up = "z"``, ``units =
    "m"`` (see :func:`motion.skeletons.canonical_skeleton`). With ``dims=2`` a 3D
    motion is turned to face the viewer at its first frame and seen from the front:
    ``(across, up)`` in metres on the 2D twin of its skeleton. 2D motions are returned
    as they are (they are drawn in their own image coordinates).
    """
    skeleton = get_skeleton(motion.skeleton)
    if fps and abs(fps - motion.fps) > _EPS:
        motion = resample(motion, fps)
    if skeleton.dims == 2:
        return motion
    upright = canonical_skeleton(skeleton)
    if upright is not skeleton:
        scale = skeleton.metres_per_unit
        matrix = axis_rotation(skeleton.up, "z") * scale
        motion = transform(motion, matrix, upright.name)
    if dims == 3:
        return motion
    return _front_view(motion, upright)


def _front_view(motion: Motion, skeleton) -> Motion:
    """Return a z-up motion turned to face -y at its first frame, as (x, z) in 2D."""
    left = [j for j in skeleton.left if skeleton.parents[j] == skeleton.root] or list(skeleton.left)
    right = [j for j in skeleton.right if skeleton.parents[j] == skeleton.root] or list(skeleton.right)
    joints = motion.joints.astype(np.float64)
    turn = np.eye(3)
    if left and right and motion.frames:
        across = joints[0, left].mean(axis=0) - joints[0, right].mean(axis=0)
        forward = np.cross(across, [0.0, 0.0, 1.0])
        if math.hypot(forward[0], forward[1]) > 1e-9:
            # A person facing the viewer (at -y) has their left at +x on the image.
            angle = -math.pi / 2 - math.atan2(forward[1], forward[0])
            cos, sin = math.cos(angle), math.sin(angle)
            turn = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
    project = (np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ turn).astype(np.float32)
    flat = flat_skeleton(skeleton)
    return Motion(joints.astype(np.float32) @ project.T, flat.name, motion.fps, motion.action,
                  motion.source, meta=dict(motion.meta), text=motion.text)

"""Render motions to videos and posters named by content, one framing for a whole set."""

from __future__ import annotations

import json
import multiprocessing
import os
import socket
import threading
import uuid
from collections import deque
from contextlib import ExitStack
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from motion import ops
from motion.motion import Motion, MotionError
from motion.skeletons import get_skeleton
from rendering.framing import Framing
from rendering.styles import Style, get_style
from rendering.video import (
    FORMATS,
    OverBudget,
    VideoWriter,
    encoder_settings,
    file_hash,
    save_poster,
)

SIDECAR = "renders.json"
# Changes whenever the same motions and settings would give other pixels or bytes (the
# camera rule, the encoder, the padding): caches of rendered clips should key on it.
VERSION = 8


class RenderError(ValueError):
    """A motion cannot be rendered (no frames, wrong shape, non-finite joints, ...)."""


@dataclass(frozen=True)
class RenderedClip:
    """One rendered motion: where its files are and what they hold."""

    index: int
    video: Path
    poster: Path
    video_hash: str
    motion_hash: str
    frames: int
    fps: float
    duration: float
    size: tuple[int, int]
    extras: dict[str, Path] = field(default_factory=dict)  # format -> file, beside the mp4


@dataclass
class RenderReport:
    """The clips rendered (in input order) and the ``(index, message)`` of those that failed."""

    clips: list[RenderedClip] = field(default_factory=list)
    failures: list[tuple[int, str]] = field(default_factory=list)
    framing: Framing | None = None
    sidecar: Path | None = None


def resample(motion: Motion, fps: float) -> Motion:
    """Return the motion at another frame rate, interpolating linearly in time."""
    if fps == motion.fps or motion.frames < 2:
        return motion.with_joints(motion.joints, fps=fps)
    count = int(np.floor((motion.frames - 1) * fps / motion.fps + 1e-6)) + 1
    times = np.arange(count) * (motion.fps / fps)
    low = np.minimum(np.floor(times).astype(int), motion.frames - 1)
    high = np.minimum(low + 1, motion.frames - 1)
    weight = (times - low)[:, None, None]
    joints = motion.joints[low] * (1 - weight) + motion.joints[high] * weight
    return motion.with_joints(joints.astype(np.float32), fps=fps)


def check(motion: Motion, style: type[Style]) -> None:
    """Raise :class:`RenderError` unless a style can draw the motion."""
    try:
        skeleton = get_skeleton(motion.skeleton)
    except KeyError as exc:
        raise RenderError(exc.args[0]) from None
    joints = np.asarray(motion.joints)
    if joints.ndim != 3 or joints.shape[1:] != (skeleton.n_joints, skeleton.dims):
        raise RenderError(
            f"joints of shape {joints.shape} do not fit skeleton {skeleton.name!r} "
            f"({skeleton.n_joints} joints in {skeleton.dims}D)"
        )
    if joints.shape[0] == 0:
        raise RenderError("the motion has no frames; nothing to render")
    if skeleton.dims != style.dims:
        raise RenderError(
            f"style {style.name!r} draws {style.dims}D skeletons; this motion is "
            f"{skeleton.dims}D ({skeleton.name!r})"
        )
    try:
        motion.check_finite()
    except MotionError as exc:
        raise RenderError(str(exc)) from None


def _dimensions(size) -> tuple[int, int]:
    width, height = (size, size) if np.isscalar(size) else size
    width, height = int(width), int(height)
    if width <= 0 or height <= 0 or width % 2 or height % 2:
        raise ValueError(
            f"video sizes must be positive and even (H.264, yuv420p); got {width}x{height}"
        )
    return width, height


def _formats(formats) -> tuple[str, ...]:
    """Return the video formats to write, checked: mp4 first, each known, none twice."""
    formats = (formats,) if isinstance(formats, str) else tuple(formats)
    unknown = sorted(set(formats) - set(FORMATS))
    if unknown:
        raise ValueError(f"unknown video formats {unknown}; choose from {', '.join(FORMATS)}")
    if "mp4" not in formats:
        raise ValueError("formats must include 'mp4': every clip has one, and is named by it")
    return ("mp4",) + tuple(dict.fromkeys(f for f in formats if f != "mp4"))


RATE_SCALES = (1.0, 0.8, 0.6, 0.4)  # a clip over its byte budget is encoded again, lower


def _encode(style: Style, motion: Motion, videos: list[Path], poster: Path,
            background: bool = True) -> int:
    """Stream a motion's frames into every video, save its middle frame; return the count.

    Every file comes out at its budget's size; the rare clip whose encoder overshoots it
    is drawn and encoded again at a lower rate.
    """
    for scale in RATE_SCALES[:-1]:
        try:
            return _encode_at(style, motion, videos, poster, scale, background)
        except OverBudget:
            pass
    return _encode_at(style, motion, videos, poster, RATE_SCALES[-1], background)


def _encode_at(style: Style, motion: Motion, videos: list[Path], poster: Path, scale,
               background: bool = True) -> int:
    middle = (motion.frames - 1) // 2
    with ExitStack() as stack:
        writers = [
            stack.enter_context(
                VideoWriter(video, style.width, style.height, motion.fps, rate_scale=scale,
                            background=background)
            )
            for video in videos
        ]
        for number, frame in enumerate(style.frames(motion)):
            for writer in writers:
                writer.write(frame)
            if number == middle:
                save_poster(poster, frame)
    return writers[0].frames


def render_motion(
    motion: Motion,
    path: str | Path,
    style: str = "stick",
    framing: Framing | None = None,
    size=480,
    fps: float | None = None,
    formats=("mp4",),
) -> RenderedClip:
    """Render one motion to the mp4 ``path`` and a poster beside it (same name, ``.png``).

    Without ``framing`` the clip is framed alone; pass a set's framing to match it.
    ``formats`` may add ``"webm"`` and ``"gif"``, written beside the mp4.
    """
    style_class = get_style(style)
    width, height = _dimensions(size)
    formats = _formats(formats)
    given = motion
    motion = ops.canonical(motion, style_class.dims, fps)  # z-up metres, as in render_set
    check(motion, style_class)
    framing = framing or Framing.from_motions(
        [motion], aspect=width / height, pad=style_class.pad
    )
    path = Path(path)
    videos = [path] + [path.with_suffix(f".{f}") for f in formats[1:]]
    with style_class(framing, width, height) as drawer:
        clip = _render_file(drawer, 0, motion, fps, videos, path.with_suffix(".png"))
    return replace(clip, motion_hash=given.content_hash())


def _render_file(drawer: Style, index, motion: Motion, fps, videos: list[Path], poster: Path,
                 background: bool = True):
    """Render into ``videos`` (the mp4 first) and ``poster``; describe the result."""
    timed = resample(motion, fps) if fps else motion
    frames = _encode(drawer, timed, videos, poster, background)
    video = videos[0]
    return RenderedClip(
        index=index,
        video=video,
        poster=poster,
        video_hash=file_hash(video),
        motion_hash=motion.content_hash(),
        frames=frames,
        fps=float(timed.fps),
        duration=frames / float(timed.fps),
        size=(drawer.width, drawer.height),
        extras={video.suffix[1:]: video for video in videos[1:]},
    )


def _render_hashed(drawer: Style, index: int, motion: Motion, fps, out_dir: Path,
                   formats: tuple[str, ...], background: bool = True) -> RenderedClip:
    """Render into temporary files, then name them all by the mp4's hash."""
    stem = out_dir / f".rendering-{os.getpid()}-{index}"
    videos = [stem.with_suffix(f".{f}") for f in formats]
    poster = stem.with_suffix(".png")
    try:
        clip = _render_file(drawer, index, motion, fps, videos, poster, background)
        named = {path: out_dir / f"{clip.video_hash}{path.suffix}" for path in videos + [poster]}
        for temporary, final in named.items():
            os.replace(temporary, final)
    finally:
        for path in videos + [poster]:
            path.unlink(missing_ok=True)
    extras = {kind: named[path] for kind, path in clip.extras.items()}
    return replace(clip, video=named[videos[0]], poster=named[poster], extras=extras)


def _attempt(drawer: Style, index: int, motion: Motion, fps, out_dir: Path, formats,
             background: bool = True):
    """Return a rendered clip, or ``(index, message)`` if it failed."""
    try:
        return _render_hashed(drawer, index, motion, fps, out_dir, formats, background)
    except Exception as exc:  # one bad clip must not stop the set
        return index, f"{type(exc).__name__}: {exc}"


_WORKER: dict = {}


def _start_worker(style: str, framing: Framing, width: int, height: int) -> None:
    _WORKER["drawer"] = get_style(style)(framing, width, height)


def _work(index: int, motion: Motion, fps, out_dir: Path, formats):
    # Rendering processes share the cores: each encodes in its drawing thread (VideoWriter).
    return _attempt(_WORKER["drawer"], index, motion, fps, out_dir, formats, background=False)


_KEPT: dict = {}  # this process's drawer for one clip at a time (render_clip)


def render_clip(motion: Motion, out_dir: str | Path, style: str, framing: Framing, size=480,
                fps: float | None = None) -> RenderedClip:
    """Render one clip of a set to ``out_dir/<hash>.mp4`` and ``<hash>.png``, as
    :func:`render_set` does (the same bytes), for a process that is handed clips one by
    one (a render worker of a fanned-out build).

    The drawer is kept between calls with the same style, framing and size. The files are
    written under names of their own (host, process, a random part) and then renamed to
    their hash, so processes on many machines may write into one shared folder and two
    drawing one clip leave one pair of files.
    """
    style_class = get_style(style)
    width, height = _dimensions(size)
    if fps is not None and not fps > 0:
        raise ValueError(f"fps must be positive; got {fps!r}")
    drawn = ops.canonical(motion, style_class.dims, fps)
    check(drawn, style_class)
    key = (style, json.dumps(framing.as_dict(), sort_keys=True, default=list), width, height)
    if _KEPT.get("key") != key:
        if _KEPT.get("drawer") is not None:
            _KEPT.pop("drawer").close()
        _KEPT.update(key=key, drawer=style_class(framing, width, height))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = out_dir / f".rendering-{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:12]}"
    videos, poster = [stem.with_suffix(".mp4")], stem.with_suffix(".png")
    try:
        clip = _render_file(_KEPT["drawer"], 0, drawn, fps, videos, poster, background=False)
        video, still = out_dir / f"{clip.video_hash}.mp4", out_dir / f"{clip.video_hash}.png"
        os.replace(poster, still)  # the poster first: a present mp4 means both are there
        os.replace(videos[0], video)
    finally:
        for path in videos + [poster]:
            path.unlink(missing_ok=True)
    return replace(clip, video=video, poster=still, motion_hash=motion.content_hash())


def render_set(
    motions: list[Motion],
    out_dir: str | Path,
    style: str = "stick",
    size=480,
    fps: float | None = None,
    workers: int = 1,
    progress: bool = True,
    framing: Framing | None = None,
    follow: bool = True,
    formats=("mp4",),
    on_clip=None,
) -> RenderReport:
    """Render every motion in one framing to ``out_dir/<hash>.mp4`` and ``<hash>.png``.

    Clips that cannot be rendered are listed in ``failures``; the rest still render.
    ``fps`` resamples every clip to one rate (``None`` keeps each motion's own).
    ``framing`` reuses another set's framing (pass the study's, so that catch, reference
    and example clips rendered later keep its rule); otherwise one is fitted to these
    motions, measured on the real ones (``follow``: the camera tracks each root
    horizontally; ``False`` keeps it still). ``out_dir/renders.json``
    records what was rendered from what, for the researcher only: never serve it.
    ``formats`` may add ``"webm"`` (VP9) and ``"gif"``, as ``<hash>.webm`` and
    ``<hash>.gif`` beside the mp4. ``workers > 1`` spawns ``workers - 1`` processes (and
    renders in this one too), so a calling script needs the ``if __name__ ==
    "__main__":`` guard. ``on_clip(index)`` is called
    as each clip is done (rendered or failed), e.g. to show progress.
    """
    style_class = get_style(style)
    width, height = _dimensions(size)
    formats = _formats(formats)
    if fps is not None and not fps > 0:
        raise ValueError(f"fps must be positive; got {fps!r}")
    out_dir = Path(out_dir)
    report = RenderReport()
    failed: dict[int, str] = {}
    ready = []
    given = motions
    # Every style draws z-up metres: each skeleton's axes and units are applied here, once.
    motions = [ops.canonical(motion, style_class.dims, fps) for motion in given]
    for index, motion in enumerate(motions):
        try:
            check(motion, style_class)
            ready.append(index)
        except RenderError as exc:
            failed[index] = str(exc)
    folder_problem = _unwritable(out_dir)
    if folder_problem:
        failed.update({index: folder_problem for index in ready})
        ready = []
    if ready:
        report.framing = framing or Framing.from_motions(
            [motions[i] for i in ready], aspect=width / height, follow=follow, pad=style_class.pad
        )

    results = []
    bar = tqdm(total=len(ready), unit="clip", desc="rendering", disable=not progress)
    done = _Progress(bar, on_clip)
    if ready and (workers <= 1 or len(ready) == 1):
        with style_class(report.framing, width, height) as drawer:
            for index in ready:
                results.append(_attempt(drawer, index, motions[index], fps, out_dir, formats))
                done(index)
    elif ready:
        results = _render_parallel(
            motions, ready, style, report.framing, (width, height), fps, out_dir, workers, done,
            formats,
        )
    bar.close()

    for result in results:
        if isinstance(result, RenderedClip):
            report.clips.append(replace(result, motion_hash=given[result.index].content_hash()))
        else:
            failed[result[0]] = result[1]
    report.clips.sort(key=lambda clip: clip.index)
    report.failures = sorted(failed.items())
    if not folder_problem:
        shots = _shots(style_class, report, motions, (width, height), fps)
        report.sidecar = _write_sidecar(
            out_dir, report, given, style, (width, height), fps, formats, shots
        )
    return report


def _shots(style_class, report: RenderReport, motions, size, fps) -> dict[int, dict]:
    """Return, per rendered clip, how its shot filmed it (for the researcher's sidecar):
    how much farther away than the rule (``zoom``), how far its window moved (pixels,
    x and y) and whether a still camera followed it."""
    if not report.clips:
        return {}
    out = {}
    with style_class(report.framing, *size) as drawer:
        for clip in report.clips:
            motion = motions[clip.index]
            motion = resample(motion, fps) if fps else motion
            shot = report.framing.shot(motion, *size, drawer.reach(motion.skeleton))
            moved = np.abs(shot.offsets).max(axis=0) if len(shot.offsets) else [0, 0]
            out[clip.index] = {
                "zoom": round(shot.framing.distance / report.framing.distance, 4),
                "window": [int(v) for v in moved],
                "follows": bool(shot.framing.follow and not report.framing.follow),
            }
    return out


class _Progress:
    """Count a finished clip on the bar and tell the caller's ``on_clip``."""

    def __init__(self, bar, on_clip):
        self.bar, self.on_clip = bar, on_clip

    def __call__(self, index: int) -> None:
        self.bar.update()
        if self.on_clip is not None:
            self.on_clip(index)


def _render_parallel(motions, ready, style, framing, size, fps, out_dir, workers, done, formats):
    """Render ``ready`` in ``workers`` processes: this one and ``workers - 1`` spawned ones.

    Spawned workers start slowly (a new interpreter imports the renderer), so this
    process draws at once, taking clips from the end of the list, while each worker is
    handed the next clip from its front whenever it finishes one (never more than one
    waiting per worker, so the two ends meet with no one idle for long). If the workers
    die, this process renders what they had not been given.
    """
    # Spawned, not forked: the caller may hold threads (torch, Django) a fork would copy.
    context = multiprocessing.get_context("spawn")
    pending = deque(ready)
    futures: dict = {}
    reported: set = set()
    results = []
    lock = threading.Lock()
    stopped = False

    spawned = min(workers, len(ready)) - 1
    with ProcessPoolExecutor(
        max_workers=spawned,
        mp_context=context,
        initializer=_start_worker,
        initargs=(style, framing, *size),
    ) as pool:

        def hand_out(_finished=None) -> None:
            """Give a worker the next clip from the front (also as a clip finishes)."""
            with lock:
                if stopped or not pending:
                    return
                index = pending.popleft()
                try:
                    future = pool.submit(_work, index, motions[index], fps, out_dir, formats)
                except Exception:  # the pool is broken: this process renders the rest
                    pending.appendleft(index)
                    return
                futures[future] = index
            future.add_done_callback(hand_out)

        def report(future) -> None:
            try:
                results.append(future.result())
            except Exception as exc:  # a worker died; its clip fails, the others go on
                results.append((futures[future], f"{type(exc).__name__}: {exc}"))
            reported.add(future)
            done(futures[future])

        try:
            for _ in range(spawned):
                hand_out()
            with get_style(style)(framing, *size) as drawer:
                while True:
                    with lock:
                        if not pending:
                            break
                        index = pending.pop()
                    results.append(_attempt(drawer, index, motions[index], fps, out_dir,
                                            formats, background=False))
                    done(index)
                    with lock:
                        finished = [f for f in futures if f.done() and f not in reported]
                    for future in finished:
                        report(future)
            with lock:
                left = [f for f in futures if f not in reported]
            for future in as_completed(left):
                report(future)
        except BaseException:
            with lock:
                stopped = True
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    return results


def _unwritable(out_dir: Path) -> str | None:
    """Return why files cannot be written to ``out_dir``, or ``None`` if they can."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / f".rendering-probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        return f"cannot write to the output folder {out_dir}: {exc.strerror or exc}"
    return None


def _write_sidecar(out_dir: Path, report: RenderReport, motions, style, size, fps,
                   formats=("mp4",), shots=None) -> Path:
    """Record what was rendered from what; names the sources, so never serve it."""
    entries = [
        {
            "index": clip.index,
            "video": clip.video.name,
            "poster": clip.poster.name,
            "video_hash": clip.video_hash,
            "motion_hash": clip.motion_hash,
            "action": motions[clip.index].action,
            "source": motions[clip.index].source,
            "skeleton": motions[clip.index].skeleton,
            "frames": clip.frames,
            "fps": clip.fps,
            "duration": clip.duration,
            "extras": {kind: path.name for kind, path in clip.extras.items()},
            "shot": (shots or {}).get(clip.index),
        }
        for clip in report.clips
    ]
    record = {
        "version": VERSION,
        "style": style,
        "size": list(size),
        "fps": fps,
        "encoder": encoder_settings(),
        "formats": list(formats),
        "framing": report.framing.as_dict() if report.framing else None,
        "clips": entries,
        "failures": [{"index": i, "message": message} for i, message in report.failures],
    }
    path = out_dir / SIDECAR
    path.write_text(json.dumps(record, indent=2) + "\n")
    return path

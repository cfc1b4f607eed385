"""Stream frames to videos (H.264 mp4, VP9 WebM, GIF) and save poster images.

The encoder settings are one constant per format, and the files carry no metadata
(no title, encoder or creation time), so identical frames give identical bytes. Frames
go to the encoder one at a time, so memory does not grow with a clip's length.
"""

from __future__ import annotations

import hashlib
import queue
import subprocess
import tempfile
import threading
from fractions import Fraction
from pathlib import Path

import imageio_ffmpeg
import numpy as np
from PIL import Image

ENCODER = [
    "-preset", "superfast",  # encoding keeps pace with drawing (veryfast: ~20 % slower, half the size)
    "-crf", "18",
    "-threads", "1",  # x264's output depends on its thread count; fix it everywhere
    "-movflags", "+faststart",
    "-map_metadata", "-1",
    "-metadata:s:v:0", "encoder=",
    "-fflags", "+bitexact",
    "-flags:v", "+bitexact",
    "-bsf:v", "filter_units=remove_types=6",  # drop x264's SEI banner with its settings
]
WEBM_ENCODER = [
    "-b:v", "0",
    "-crf", "33",
    "-deadline", "good",
    "-cpu-used", "5",
    "-row-mt", "0",
    "-threads", "1",  # one thread: libvpx's output then never depends on scheduling
    "-map_metadata", "-1",
    "-metadata:s:v:0", "encoder=",
    "-fflags", "+bitexact",
    "-flags:v", "+bitexact",
]
# GIFs share one palette, taken from the first frame: the scenery and the figure's
# colours are all in it, and a palette per frame would flicker.
GIF_FILTER = "[0:v][1:v]paletteuse=dither=bayer:bayer_scale=4:diff_mode=rectangle"
FORMATS = ("mp4", "webm", "gif")


class VideoWriter:
    """Write ``(H, W, 3)`` uint8 frames one at a time (use as a context manager).

    The format follows the file's suffix: ``.mp4`` (H.264), ``.webm`` (VP9) or
    ``.gif``. If the block raises, the partial file is removed.
    """

    def __init__(self, path: str | Path, width: int, height: int, fps: float):
        self.path = Path(path)
        self.format = self.path.suffix[1:].lower()
        if self.format not in FORMATS:
            raise ValueError(f"videos are one of {', '.join(FORMATS)}; got {self.path.name!r}")
        if self.format != "gif" and (width % 2 or height % 2):
            raise ValueError(f"{self.format} in yuv420p needs even sizes; got {width}x{height}")
        self.width, self.height = width, height
        self.fps = Fraction(fps).limit_denominator(1001)
        self.frames = 0
        self._writer = None if self.format == "gif" else self._yuv_writer()
        # Frames go to ffmpeg from a thread of their own: a frame is larger than the
        # pipe's buffer, so a direct write would wait for ffmpeg to read it, and the
        # next frame could not be drawn while ffmpeg encodes this one.
        self._pending: queue.Queue = queue.Queue(maxsize=4)
        self._failure: BaseException | None = None
        self._sender = threading.Thread(target=self._send_pending, daemon=True)
        self._sender.start()

    def _yuv_writer(self):
        mp4 = self.format == "mp4"
        writer = imageio_ffmpeg.write_frames(
            str(self.path),
            (self.width, self.height),
            pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p",
            fps=self.fps,
            quality=None,
            codec="libx264" if mp4 else "libvpx-vp9",
            macro_block_size=2,
            ffmpeg_log_level="error",
            output_params=list(ENCODER if mp4 else WEBM_ENCODER),
        )
        writer.send(None)
        return writer

    def write(self, frame: np.ndarray) -> None:
        """Append one frame."""
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frames must be ({self.height}, {self.width}, 3) uint8; "
                f"got {frame.shape} {frame.dtype}"
            )
        if self._failure is not None:
            raise RuntimeError(f"ffmpeg stopped writing {self.path}: {self._failure}")
        if self._writer is None:
            self._writer = _GifPipe(self.path, np.ascontiguousarray(frame), self.fps)
        self._pending.put(frame.tobytes())  # a copy: the caller may reuse its buffer
        self.frames += 1

    def _send_pending(self) -> None:
        while (data := self._pending.get()) is not None:
            if self._failure is None:
                try:
                    self._writer.send(data)
                except BaseException as exc:  # reported by write() and close()
                    self._failure = exc

    def close(self) -> None:
        """Finish the file (an mp4 gets its index at the front)."""
        if self._sender.is_alive():
            self._pending.put(None)
            self._sender.join()
        if self._failure is not None:
            raise RuntimeError(f"ffmpeg stopped writing {self.path}: {self._failure}")
        if self._writer is not None:
            self._writer.close()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            self.close()
        finally:
            if exc_type is not None:
                self.path.unlink(missing_ok=True)


class _GifPipe:
    """An ffmpeg process turning raw frames into a GIF with the first frame's palette."""

    def __init__(self, path: Path, first: np.ndarray, fps: Fraction):
        self._folder = tempfile.TemporaryDirectory(prefix="gif-palette-")
        palette = Path(self._folder.name) / "palette.png"
        colours = Image.fromarray(first).quantize(256, method=Image.Quantize.MEDIANCUT)
        swatch = np.zeros(768, np.uint8)
        swatch[: len(colours.getpalette())] = colours.getpalette()[:768]
        Image.fromarray(swatch.reshape(16, 16, 3)).save(palette)
        height, width = first.shape[:2]
        command = [
            imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error",
            "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", str(fps),
            "-i", "-", "-i", str(palette), "-lavfi", GIF_FILTER,
            "-loop", "0", "-map_metadata", "-1", "-fflags", "+bitexact", str(path),
        ]
        self._process = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )

    def send(self, data: bytes) -> None:
        self._process.stdin.write(data)

    def close(self) -> None:
        try:
            self._process.stdin.close()
            errors = self._process.stderr.read().decode(errors="replace").strip()
            if self._process.wait() != 0:
                raise RuntimeError(f"ffmpeg could not write the GIF: {errors}")
        finally:
            self._folder.cleanup()


def save_poster(path: str | Path, frame: np.ndarray) -> Path:
    """Save a frame as a PNG without metadata."""
    path = Path(path)
    Image.fromarray(frame).save(path, format="PNG", optimize=False, compress_level=6)
    return path


def file_hash(path: str | Path, length: int = 16) -> str:
    """Return the first ``length`` hex digits of a file's sha256."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:length]

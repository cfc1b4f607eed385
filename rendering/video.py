"""Stream frames to videos (H.264 mp4, VP9 WebM, GIF) and save poster images.

Nothing a participant can observe about a clip's files depends on what it shows: the
encoders run at a constant bit rate per pixel (x264 adds filler data to keep it), with
no content-dependent choices (no scene-cut keyframes, no B-frames, so the mp4's tables
are the same for every clip of one length), and every file is padded to one byte size
per format, resolution, length and frame rate (:func:`budget`, see
:mod:`rendering.padding`). The files carry no metadata (no title, encoder or creation
time), so identical frames give identical bytes. Frames go to the encoder as they are
drawn (at most a few at a time), so memory does not grow with a clip's length. H.264 is
encoded in this process (libx264 through PyAV); VP9 and GIF by an ``ffmpeg`` process
reading raw frames.
"""

from __future__ import annotations

import fcntl
import hashlib
import io
import math
import queue
import subprocess
import tempfile
import threading
from fractions import Fraction
from pathlib import Path

import cv2
import imageio_ffmpeg
import numpy as np
from PIL import Image

from rendering.delivery import MAX_FILL_CHUNKS, MAX_FILLERS
from rendering.padding import PaddingError, equalise_mp4_frames, pad

# Bits per pixel and frame: at 480x480 and 25 fps, 259 kbit/s, about 78 KB for 60 frames;
# small videos (thumbnails) get at least 64 kbit/s.
BITS_PER_PIXEL = 0.045
MIN_BIT_RATE = 64_000
# Room above the constant rate's bytes for what an encoder overshoots (x264 stays within
# about 10 %, libvpx within 20 %) and the container's tables, per file and per frame.
HEADROOM = {"mp4": 1.15, "webm": 1.3}
# An mp4 lists every frame's byte size, so each is padded to a fixed budget: a keyframe to
# the encoder's buffer (this many frames of the rate), every other frame to this multiple
# of the rate's mean (frames over it: encoded again, lower). At 1.5 a third of the demo's
# walking clips were encoded twice or three times; at 2 none of 48 was.
BUFFER_FRAMES = 5
FRAME_HEADROOM = 2.0
# Every padded frame keeps at least this much filler data, so that each delivery can split
# it into 1 to MAX_FILLERS units (rendering.delivery) however full the encoder left the
# frame: without it, a busier clip's frames held fewer units, which a script could count.
FILLER_ROOM = MAX_FILLERS * (4 + 2)  # NAL units of a 4-byte length, a header and a trailer
KEYINT = 250
OVERHEAD = {"mp4": (2048, 24), "webm": (2048, 24)}
# GIFs have no rate control, so their budget is LZW's worst case (12-bit codes for 8-bit
# pixels, plus the sub-blocks' length bytes): large; prefer mp4 or WebM.
GIF_BYTES_PER_PIXEL = 1.51
# Poster budgets: 4 KiB and this much per pixel. The middle frames of 16 demo clips took
# up to 0.38 byte per pixel beyond the 4 KiB at 128 and 240 pixels, 0.27 at 480 (PNG
# level 3); a busier frame is stored with fewer colours (save_poster).
POSTER_BYTES_PER_PIXEL = 0.4
POSTER_COLOURS = (256, 64, 16)  # a busier poster is reduced to these many colours in turn
BLOCK = 1024  # budgets are whole KiB
FORMATS = ("mp4", "webm", "gif")


def bit_rate(width: int, height: int, fps, scale: float = 1.0) -> int:
    """Return the constant bit rate (bits per second) of a video of this size and rate."""
    return int(scale * max(BITS_PER_PIXEL * width * height * float(fps), MIN_BIT_RATE))


def frame_budgets(width: int, height: int, fps) -> tuple[int, int]:
    """Return the byte sizes every mp4 keyframe and every other frame is padded to."""
    mean = bit_rate(width, height, fps) / 8 / float(fps)
    return (int(math.ceil(BUFFER_FRAMES * mean)) + FILLER_ROOM,
            int(math.ceil(FRAME_HEADROOM * mean)) + FILLER_ROOM)


def budget(kind: str, width: int, height: int, frames: int, fps) -> int:
    """Return the byte size of every ``kind`` file (mp4, webm, gif, png) of these dimensions.

    It depends on nothing else, so a clip's size tells nothing about its content.
    """
    if kind == "mp4":
        key, other = frame_budgets(width, height, fps)
        keys = -(-frames // KEYINT)
        fixed, per_frame = OVERHEAD[kind]
        size = keys * key + (frames - keys) * other + fixed + per_frame * frames
    elif kind == "png":
        size = POSTER_BYTES_PER_PIXEL * width * height + 4096
    elif kind == "gif":
        size = (GIF_BYTES_PER_PIXEL * width * height + 1024) * frames + 4096
    else:
        payload = bit_rate(width, height, fps) / 8 * frames / float(fps)
        fixed, per_frame = OVERHEAD[kind]
        size = payload * HEADROOM[kind] + fixed + per_frame * frames
    return int(math.ceil(size / BLOCK) * BLOCK)


def mp4_qp_floor(scale: float) -> int:
    """Return x264's lowest quantiser for an mp4 encoded again at ``scale`` (< 1).

    An mp4's stream parameters (its SPS, read by anyone) carry the rate, so a clip over
    its budget keeps the rate and is quantised more coarsely instead: nothing in its
    headers then tells that it was encoded again.
    """
    return 0 if scale >= 1 else int(round(24 + 30 * (1 - scale)))


def x264_options(width: int, height: int, fps, scale: float = 1.0) -> dict[str, str]:
    """Return libx264's settings for a constant-rate mp4, by ffmpeg's option names.

    ``scale`` < 1 marks a clip encoded again to fit its budget: it keeps the rate (which
    its stream parameters carry) and gets a coarser quantiser floor (:func:`mp4_qp_floor`).
    """
    rate = bit_rate(width, height, fps)
    return {
        "preset": "superfast",
        "b": str(rate), "minrate": str(rate), "maxrate": str(rate),
        # A buffer of a few frames with a constant-rate HRD: x264 keeps every frame near
        # the rate (the keyframe within the buffer), and the writer pads each frame to its
        # fixed budget (padding.equalise_mp4_frames).
        "bufsize": str(int(rate * BUFFER_FRAMES / float(fps))),
        # Keyframes every KEYINT frames whatever is shown, no B-frames: frame types and so
        # the mp4's tables never depend on content.
        "x264-params": f"filler=1:nal-hrd=cbr:bframes=0:scenecut=0:keyint={KEYINT}"
                       f":min-keyint={KEYINT}:qpmin={mp4_qp_floor(scale)}",
    }


# x264 writes its version and settings into the stream (an SEI message): dropped.
DROP_X264_BANNER = "filter_units=remove_types=6"


def encoder_options(kind: str, width: int, height: int, fps, scale: float = 1.0) -> list[str]:
    """Return ffmpeg's command-line output options for a constant-rate mp4 or WebM
    (``scale`` < 1: a clip encoded again to fit its budget: a lower rate for WebM, a
    coarser floor for mp4). The mp4 ones are what :class:`VideoWriter` sets in-process."""
    common = ["-map_metadata", "-1", "-metadata:s:v:0", "encoder=", "-fflags", "+bitexact",
              "-flags:v", "+bitexact"]
    if kind == "mp4":
        settings = x264_options(width, height, fps, scale)
        return [
            "-preset", settings["preset"], "-b:v", settings["b"],
            *(item for key in ("minrate", "maxrate", "bufsize", "x264-params")
              for item in (f"-{key}", settings[key])),
            "-threads", "1",  # x264's output depends on its thread count; fix it everywhere
            "-movflags", "+faststart",
            *common,
            "-bsf:v", DROP_X264_BANNER,
        ]
    rate = bit_rate(width, height, fps, scale)
    return [
        "-b:v", str(rate), "-minrate", str(rate), "-maxrate", str(rate),
        "-deadline", "good",
        "-cpu-used", "5",
        "-row-mt", "0",
        "-auto-alt-ref", "0",  # no hidden frames placed by content
        "-g", "250",
        "-threads", "1",  # one thread: libvpx's output then never depends on scheduling
        *common,
    ]


def encoder_settings() -> dict:
    """Return the encoding rule, for the researcher's record."""
    return {"bits_per_pixel": BITS_PER_PIXEL, "headroom": HEADROOM,
            "mp4": encoder_options("mp4", 2, 2, 1)[:2] + ["constant rate, filler, no B-frames"],
            "padded": True}


# Rendering processes share the cores (one per core): OpenCV's own thread pool would
# only make them contend.
cv2.setNumThreads(1)


def to_yuv420p(frame: np.ndarray) -> np.ndarray:
    """Return an RGB frame ``(H, W, 3)`` uint8 as yuv420p planes ``(3 H / 2, W)`` uint8.

    BT.601 in limited range, as ffmpeg converts RGB for H.264 by default: the same luma
    (within one level), and each chroma sample from the mean colour of its 2×2 pixels
    (OpenCV's own I420 conversion takes the top-left pixel's, which lets thin coloured
    edges flicker; ffmpeg's default filters chroma with a wider bicubic kernel, so colour
    edges differ from its by a few levels). About 0.2 ms a 480×480 frame here, against
    0.5 for ffmpeg's bicubic scaler, most of what x264 itself takes per frame (0.7).
    """
    frame = np.ascontiguousarray(frame)
    height, width = frame.shape[:2]
    planes = cv2.cvtColor(frame, cv2.COLOR_RGB2YUV_I420)  # its luma; chroma replaced below
    means = cv2.resize(frame, (width // 2, height // 2), interpolation=cv2.INTER_AREA)
    # OpenCV's YCrCb is full range (JPEG's); limited range is 128 + (c - 128) * 224 / 255.
    chroma = cv2.convertScaleAbs(cv2.cvtColor(means, cv2.COLOR_RGB2YCrCb),
                                 alpha=224 / 255, beta=128 * (1 - 224 / 255))
    quarter = height * width // 4
    flat = planes.reshape(-1)
    for channel, start in ((2, height * width), (1, height * width + quarter)):  # Cb, Cr
        plane = flat[start:start + quarter].reshape(height // 2, width // 2)
        cv2.extractChannel(chroma, channel, dst=plane)
    return planes


class OverBudget(RuntimeError):
    """A file came out larger than its budget; encode it again at a lower rate."""


# GIFs share one palette, taken from the first frame: the scenery and the figure's
# colours are all in it, and a palette per frame would flicker.
GIF_FILTER = "[0:v][1:v]paletteuse=dither=bayer:bayer_scale=4:diff_mode=rectangle"


# Without a thread of its own, a writer encodes its frames in groups: drawing a group and
# then encoding it keeps each one's working set in the caches; alternating frame by frame
# cost about 15 % more CPU here (48 stick clips at 480x480).
BATCH_FRAMES = 16


class VideoWriter:
    """Write ``(H, W, 3)`` uint8 frames one at a time (use as a context manager).

    The format follows the file's suffix: ``.mp4`` (H.264), ``.webm`` (VP9) or
    ``.gif``. If the block raises, the partial file is removed. ``pad`` makes the file
    its :func:`budget`'s size on closing (:class:`OverBudget` if it is larger: encode
    again with a smaller ``rate_scale``). ``background=False`` hands frames to the encoder
    (x264 in this thread, or an ffmpeg pipe for WebM and GIF) from the caller's thread,
    :data:`BATCH_FRAMES` frames at a time: for processes that share the cores with other
    rendering processes, where a thread of its own gains nothing.
    """

    def __init__(self, path: str | Path, width: int, height: int, fps: float,
                 pad: bool = True, rate_scale: float = 1.0, background: bool = True):
        self.path = Path(path)
        self.format = self.path.suffix[1:].lower()
        if self.format not in FORMATS:
            raise ValueError(f"videos are one of {', '.join(FORMATS)}; got {self.path.name!r}")
        if self.format != "gif" and (width % 2 or height % 2):
            raise ValueError(f"{self.format} in yuv420p needs even sizes; got {width}x{height}")
        self.width, self.height = width, height
        self.fps = Fraction(fps).limit_denominator(1001)
        self.frames = 0
        self.pad, self.rate_scale = pad, rate_scale
        self._writer = None if self.format == "gif" else self._yuv_writer()
        self._failure: BaseException | None = None
        self._batch: list = []
        self._sender = None
        if background:
            # Frames go to the encoder from a thread of their own, so the next frame can
            # be drawn while this one is encoded: x264 in-process runs without the GIL
            # for much of its work, and an ffmpeg pipe would otherwise block on every
            # frame (a frame is larger than the pipe's buffer).
            self._pending: queue.Queue = queue.Queue(maxsize=4)
            self._sender = threading.Thread(target=self._send_pending, daemon=True)
            self._sender.start()

    def _yuv_writer(self):
        if self.format == "mp4":
            return _X264(self.path, self.width, self.height, self.fps, self.rate_scale)
        options = encoder_options(self.format, self.width, self.height, self.fps, self.rate_scale)
        return _Pipe(_raw_input(self.width, self.height, self.fps)
                     + ["-c:v", "libvpx-vp9", "-pix_fmt", "yuv420p", *options, str(self.path)])

    def write(self, frame: np.ndarray) -> None:
        """Append one frame."""
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frames must be ({self.height}, {self.width}, 3) uint8; "
                f"got {frame.shape} {frame.dtype}"
            )
        if self._failure is not None:
            raise RuntimeError(f"the encoder stopped writing {self.path}: {self._failure}")
        if self._writer is None:
            self._writer = _GifPipe(self.path, np.ascontiguousarray(frame), self.fps)
        prepared = self._writer.prepare(frame)  # a copy: the caller may reuse its buffer
        if self._sender is not None:
            self._pending.put(prepared)
        else:
            self._batch.append(prepared)
            if len(self._batch) == BATCH_FRAMES:
                self._send_batch()
        self.frames += 1

    def _send_batch(self) -> None:
        try:
            for prepared in self._batch:
                self._writer.send(prepared)
        except Exception as exc:
            raise RuntimeError(f"the encoder stopped writing {self.path}: {exc}") from exc
        finally:
            self._batch.clear()

    def _send_pending(self) -> None:
        while (data := self._pending.get()) is not None:
            if self._failure is None:
                try:
                    self._writer.send(data)
                except BaseException as exc:  # reported by write() and close()
                    self._failure = exc

    def close(self) -> None:
        """Finish the file (an mp4 gets its index at the front)."""
        try:
            if self._sender is not None and self._sender.is_alive():
                self._pending.put(None)
                self._sender.join()
            elif self._batch:
                self._send_batch()
            if self._failure is not None:
                raise RuntimeError(f"the encoder stopped writing {self.path}: {self._failure}")
        except BaseException as failure:
            # Close the encoder anyway: a pipe's ffmpeg then says why it stopped.
            if self._writer is not None:
                try:
                    self._writer.close()
                except Exception as reason:
                    raise reason from failure
            raise
        if self._writer is not None:
            self._writer.close()
        if self.pad and self.frames:
            size = budget(self.format, self.width, self.height, self.frames, self.fps)
            try:
                if self.format == "mp4":
                    equalise_mp4_frames(self.path, *frame_budgets(self.width, self.height,
                                                                  self.fps))
                pad(self.path, size)
            except PaddingError as exc:
                self.path.unlink(missing_ok=True)
                raise OverBudget(str(exc)) from None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            self._abort()  # the block's own error is the one to tell
            self.path.unlink(missing_ok=True)
            return
        try:
            self.close()
        except BaseException:
            self.path.unlink(missing_ok=True)  # no partial file is left behind
            raise

    def _abort(self) -> None:
        """Stop the encoder without finishing the file; its errors no longer matter."""
        self._batch.clear()
        if self._sender is not None and self._sender.is_alive():
            self._pending.put(None)
            self._sender.join()
        if self._writer is not None:
            try:
                self._writer.close()
            except Exception:
                pass


class _X264:
    """libx264 inside this process (through PyAV's FFmpeg libraries) writing an mp4.

    The same encoder and settings as ``ffmpeg`` with :func:`encoder_options`, so the
    same bytes from the same yuv420p frames (a test checks), without an ffmpeg process
    per clip, its start-up and a pipe carrying every frame.
    """

    def __init__(self, path: Path, width: int, height: int, fps: Fraction, scale: float):
        import av
        from av.bitstream import BitStreamFilterContext
        from av.codec.context import Flags

        self._av, self._path, self._height = av, path, height
        settings = x264_options(width, height, fps, scale)
        self._container = None
        try:
            self._container = av.open(str(path), "w", format="mp4",
                                      options={"movflags": "+faststart"},
                                      container_options={"fflags": "+bitexact"})
            self._stream = self._container.add_stream("libx264", rate=fps)
            context = self._stream.codec_context
            context.width, context.height, context.pix_fmt = width, height, "yuv420p"
            context.bit_rate = int(settings.pop("b"))
            context.thread_count = 1  # x264's output depends on its thread count
            context.flags |= int(Flags.bitexact)
            context.options = settings
            self._container.start_encoding()  # the stream's parameters, before the filter's
            self._banner = BitStreamFilterContext(DROP_X264_BANNER, self._stream, self._stream)
        except av.FFmpegError as exc:
            self._close_container()
            path.unlink(missing_ok=True)
            raise RuntimeError(f"could not start encoding {path}: {exc}") from None

    def prepare(self, frame: np.ndarray):
        """Return what :meth:`send` takes: the frame in yuv420p (:func:`to_yuv420p`), in a
        buffer of its own that the frame wraps (x264 copies it when it is sent)."""
        planes = to_yuv420p(frame)
        if self._height % 4:
            # PyAV 18's from_numpy_buffer reads the height as rows // 6 * 4: wrong (and
            # silently so) for heights of 2 more than a multiple of 4. Copy those.
            return self._av.VideoFrame.from_ndarray(planes, format="yuv420p")
        return self._av.VideoFrame.from_numpy_buffer(planes, format="yuv420p")

    def _mux(self, packets) -> None:
        for packet in packets:
            for kept in self._banner.filter(packet):
                self._container.mux(kept)

    def send(self, frame) -> None:
        self._mux(self._stream.encode(frame))

    def close(self) -> None:
        try:
            self._mux(self._stream.encode(None))
            for kept in self._banner.filter(None):
                self._container.mux(kept)
        except self._av.FFmpegError as exc:
            raise RuntimeError(f"could not finish {self._path}: {exc}") from None
        finally:
            self._close_container()

    def _close_container(self) -> None:
        try:
            if self._container is not None:
                self._container.close()
        except self._av.FFmpegError:  # already failing: the first error is the one to tell
            pass
        self._container = None


PIPE_BYTES = 1 << 20  # a whole 480x480 frame fits: one wake-up of ffmpeg per frame, not 11


def _raw_input(width: int, height: int, fps) -> list[str]:
    return ["-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", str(fps),
            "-i", "-"]


class _Pipe:
    """An ffmpeg process reading raw RGB frames on its standard input."""

    def __init__(self, arguments: list[str], describe: str = "the video"):
        command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y",
                   *arguments]
        self._describe = describe
        self._process = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        try:
            fcntl.fcntl(self._process.stdin.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
        except (AttributeError, OSError):  # not Linux, or a lower system limit: still works
            pass

    def prepare(self, frame: np.ndarray) -> bytes:
        """Return what :meth:`send` takes: a copy of the frame's bytes."""
        return frame.tobytes()

    def send(self, data: bytes) -> None:
        self._process.stdin.write(data)

    def close(self) -> None:
        self._process.stdin.close()
        errors = self._process.stderr.read().decode(errors="replace").strip()
        if self._process.wait() != 0:
            raise RuntimeError(f"ffmpeg could not write {self._describe}: {errors}")


class _GifPipe(_Pipe):
    """An ffmpeg process turning raw frames into a GIF with the first frame's palette."""

    def __init__(self, path: Path, first: np.ndarray, fps: Fraction):
        self._folder = tempfile.TemporaryDirectory(prefix="gif-palette-")
        palette = Path(self._folder.name) / "palette.png"
        colours = Image.fromarray(first).quantize(256, method=Image.Quantize.MEDIANCUT)
        swatch = np.zeros(768, np.uint8)
        swatch[: len(colours.getpalette())] = colours.getpalette()[:768]
        Image.fromarray(swatch.reshape(16, 16, 3)).save(palette)
        height, width = first.shape[:2]
        super().__init__(
            _raw_input(width, height, fps)
            + ["-i", str(palette), "-lavfi", GIF_FILTER, "-loop", "0", "-map_metadata", "-1",
               "-fflags", "+bitexact", str(path)],
            "the GIF",
        )

    def close(self) -> None:
        try:
            super().close()
        finally:
            self._folder.cleanup()


def save_poster(path: str | Path, frame: np.ndarray, padded: bool = True) -> Path:
    """Save a frame as a PNG without metadata, padded to its :func:`budget`'s size.

    A frame too busy to fit is reduced to 256 colours (then 64, then 16) and still stored
    as an RGB PNG (a palette PNG's header would tell such frames from the others); one
    that does not fit even so raises :class:`OverBudget`.
    """
    path = Path(path)
    image = Image.fromarray(frame)
    encoded = io.BytesIO()
    image.save(encoded, format="PNG", compress_level=3)  # level 9 costs 10x the time
    size = budget("png", image.width, image.height, 1, 1)
    for colours in POSTER_COLOURS:
        # room for MAX_FILL_CHUNKS padding chunks, which each delivery splits anew
        if not padded or encoded.tell() <= size - 12 * MAX_FILL_CHUNKS:
            break
        encoded = io.BytesIO()
        fewer = image.quantize(colours, method=Image.Quantize.MEDIANCUT).convert("RGB")
        fewer.save(encoded, format="PNG", compress_level=9)
    path.write_bytes(encoded.getvalue())
    if padded:
        try:
            pad(path, size)
        except PaddingError as exc:
            path.unlink(missing_ok=True)
            raise OverBudget(str(exc)) from None
    return path


def file_hash(path: str | Path, length: int = 16) -> str:
    """Return the first ``length`` hex digits of a file's sha256."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:length]

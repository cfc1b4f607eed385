"""Read rendered videos back for checks."""

import imageio_ffmpeg
import numpy as np


def decode(path) -> tuple[dict, np.ndarray]:
    """Return a video's metadata and frames ``(T, H, W, 3)`` uint8."""
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    frames = [np.frombuffer(frame, np.uint8).reshape(height, width, 3) for frame in reader]
    return meta, np.array(frames)


def figure_box(frame: np.ndarray) -> tuple[int, int, int, int] | None:
    """Return the (left, top, right, bottom) of the coloured limbs, or ``None``.

    The scenery is grey; the warm left and cool right limbs are strongly saturated.
    """
    saturation = frame.max(axis=-1).astype(int) - frame.min(axis=-1)
    ys, xs = np.nonzero(saturation > 60)
    if not len(xs):
        return None
    return xs.min(), ys.min(), xs.max(), ys.max()

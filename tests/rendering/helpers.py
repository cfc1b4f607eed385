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


def to_2d(motion):
    """Return an ``h36m17`` motion seen from its side as an ``h36m15_2d`` one (pixels, y down)."""
    from motion.skeletons import H36M15_2D_FROM_17

    joints = np.asarray(motion.joints)[:, list(H36M15_2D_FROM_17)]
    pixels = np.stack([joints[..., 0], -joints[..., 2]], axis=-1) * 200.0 + 500.0
    return motion.with_joints(pixels.astype(np.float32), skeleton="h36m15_2d")

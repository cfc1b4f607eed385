"""Measure what a participant sees of the figure: its share of the frame's height.

Frames are drawn by a style with the floor shadow left out, and compared with the bare
backdrop at the same look-at, so only the body counts.
"""

from __future__ import annotations

import numpy as np

from motion.motion import Motion
from rendering.backdrop import Backdrop
from rendering.framing import Framing
from rendering.styles import get_style
from rendering.styles.mesh import MeshStyle

THRESHOLD = 24  # colour levels a pixel must differ from the backdrop by to be the figure


def bare_style(style: str):
    """Return the style class drawing its figure without a floor shadow."""
    base = get_style(style)
    if issubclass(base, MeshStyle):
        return type("BareMesh", (base,), {"_cast_shadow": lambda self, *args: None})
    return type("Bare", (base,), {"shadow": False})


def figure_rows(frame: np.ndarray, scenery: np.ndarray, threshold: int = THRESHOLD):
    """Return the top and bottom rows where ``frame`` differs from ``scenery``, or ``None``."""
    changed = np.abs(frame.astype(int) - scenery.astype(int)).max(axis=-1) > threshold
    rows = np.nonzero(changed.any(axis=1))[0]
    return (int(rows.min()), int(rows.max())) if len(rows) else None


def figure_shares(style: str, framing: Framing, motion: Motion, size: int = 128,
                  every: int = 1) -> tuple[np.ndarray, tuple[int, int]]:
    """Return the figure's height share of every ``every``-th frame, and how many of those
    frames it touches the top and the bottom edge in."""
    if every > 1:
        motion = motion.with_joints(motion.joints[::every], fps=motion.fps / every)
    shares, top, bottom = [], 0, 0
    with bare_style(style)(framing, size, size) as drawer:
        shot = framing.shot(motion, size, size, drawer.reach(motion.skeleton))
        backdrop = Backdrop(shot.framing, size, size, shot.margin)
        for number, (frame, target) in enumerate(zip(drawer.frames(motion), shot.targets)):
            rows = figure_rows(frame, shot.cut(backdrop.image(target), number, size, size))
            if rows is None:
                shares.append(0.0)
                continue
            shares.append((rows[1] - rows[0] + 1) / size)
            top += rows[0] == 0
            bottom += rows[1] == size - 1
    return np.array(shares), (top, bottom)

"""Several motions side by side under labels: a grid video and a contact sheet.

For papers and the admin, not for participants: the labels may name methods. Every cell
is drawn by one style in one shared framing, so the cells compare directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from motion import ops
from motion.motion import Motion
from rendering.batch import RenderError, check
from rendering.framing import Framing
from rendering.styles import get_style
from rendering.video import VideoWriter, save_poster

INK = (52, 56, 64)
PAPER = (255, 255, 255)
GAP = 4  # pixels of paper between cells (even, so H.264 sizes stay even)


@dataclass(frozen=True)
class RenderedGrid:
    """Where a grid's video and contact sheet are, and what they hold."""

    video: Path
    sheet: Path
    frames: int
    fps: float
    size: tuple[int, int]
    framing: Framing


def _band(size: int) -> int:
    """Return the height of a label band over cells of ``size`` pixels (even)."""
    return max(16, size // 8) // 2 * 2


def _label_band(text: str, width: int, height: int) -> np.ndarray:
    """Return a band ``(height, width, 3)`` with ``text`` on it, shortened to fit."""
    band = Image.new("RGB", (width, height), PAPER)
    draw = ImageDraw.Draw(band)
    font = ImageFont.load_default(size=max(8, int(height * 0.62)))
    margin = height // 3
    while text and draw.textlength(text, font=font) > width - 2 * margin:
        text = text[:-2] + "…" if len(text) > 2 else ""
    draw.text((margin, height / 2), text, fill=INK, font=font, anchor="lm")
    return np.asarray(band)


def render_grid(
    motions: list[Motion],
    labels: list[str] | None,
    path: str | Path,
    style: str = "stick",
    cols: int | None = None,
    size: int = 240,
    fps: float | None = None,
    framing: Framing | None = None,
    moments: int = 6,
) -> RenderedGrid:
    """Write the motions as a labelled grid to the mp4 ``path``, and a contact sheet beside it.

    Cells are ``size`` pixels square, ``cols`` to a row (default: a near-square grid)
    and play together; a clip that ends early holds its last frame. ``labels`` default
    to each motion's source and action. The sheet (``path`` with ``.png``) shows each
    motion as a row of ``moments`` frames evenly spaced in time. ``fps`` defaults to the
    first motion's rate; others are resampled to it.
    """
    if not motions:
        raise ValueError("a grid needs at least one motion")
    labels = list(labels) if labels is not None else [f"{m.source} · {m.action}" for m in motions]
    if len(labels) != len(motions):
        raise ValueError(f"{len(labels)} labels for {len(motions)} motions")
    if size <= 0 or size % 2:
        raise ValueError(f"cell sizes must be positive and even; got {size}")
    style_class = get_style(style)
    fps = float(fps or motions[0].fps)
    # Every style draws z-up metres: each skeleton's axes and units are applied here, once.
    motions = [ops.canonical(m, style_class.dims, fps) for m in motions]
    for index, motion in enumerate(motions):
        try:
            check(motion, style_class)
        except RenderError as exc:
            raise RenderError(f"motion {index} ({labels[index]}): {exc}") from None
    framing = framing or Framing.from_motions(motions, pad=style_class.pad)
    cols = cols or math.ceil(math.sqrt(len(motions)))
    rows = math.ceil(len(motions) / cols)
    band = _band(size)
    path = Path(path)
    length = max(m.frames for m in motions)
    picks = [set(np.linspace(0, m.frames - 1, moments).round().astype(int).tolist())
             for m in motions]
    strips: list[list[np.ndarray]] = [[] for _ in motions]

    pitch_x, pitch_y = size + GAP, size + band + GAP
    canvas = np.empty((rows * pitch_y - GAP, cols * pitch_x - GAP, 3), np.uint8)
    canvas[:] = PAPER
    for index, label in enumerate(labels):
        top, left = (index // cols) * pitch_y, (index % cols) * pitch_x
        canvas[top:top + band, left:left + size] = _label_band(label, size, band)
    with style_class(framing, size, size) as drawer:
        streams = [drawer.frames(m) for m in motions]
        # Not padded: grids are for papers and the admin, never served to participants.
        with VideoWriter(path, canvas.shape[1], canvas.shape[0], fps, pad=False) as writer:
            for number in range(length):
                for index, stream in enumerate(streams):
                    if number >= motions[index].frames:
                        continue  # the cell keeps its last frame
                    frame = next(stream)
                    top, left = (index // cols) * pitch_y + band, (index % cols) * pitch_x
                    canvas[top:top + size, left:left + size] = frame
                    if number in picks[index]:
                        strips[index].append(frame)
                writer.write(canvas)
    sheet = _contact_sheet(strips, labels, size, band)
    save_poster(path.with_suffix(".png"), sheet, padded=False)
    size = (canvas.shape[1], canvas.shape[0])
    return RenderedGrid(path, path.with_suffix(".png"), length, fps, size, framing)


def _contact_sheet(strips: list[list[np.ndarray]], labels: list[str], size: int, band: int):
    """Return one row per motion: its label over its frames, left to right in time."""
    width = max(len(strip) for strip in strips) * (size + GAP) - GAP
    rows = []
    for strip, label in zip(strips, labels):
        row = np.empty((band + size + GAP, width, 3), np.uint8)
        row[:] = PAPER
        row[:band] = _label_band(label, width, band)
        for column, frame in enumerate(strip):
            left = column * (size + GAP)
            row[band:band + size, left:left + size] = frame
        rows.append(row)
    return np.concatenate(rows)[:-GAP]

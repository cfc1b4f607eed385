"""The scenery behind every figure: a soft sky and a checker floor fading into it."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from rendering import palette
from rendering.framing import Framing


def _square_wave_mean(x: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Return the mean over ``[x - width/2, x + width/2]`` of a ±1 square wave of period 2."""

    def triangle(t):  # an integral of the square wave
        t = t / 2
        return np.abs(t - np.floor(t) - 0.5)

    return 2 * (triangle(x - width / 2) - triangle(x + width / 2)) / width


def checker(u: np.ndarray, v: np.ndarray, wu: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """Return a box-filtered checker in ``[0, 1]`` at tile coordinates with footprints.

    Averaging the tiles over each pixel's footprint anti-aliases the floor exactly, so
    it needs no supersampling.
    """
    return 0.5 - 0.5 * _square_wave_mean(u, wu) * _square_wave_mean(v, wv)


def _floor(camera, framing: Framing, tile: float):
    """Return each pixel's floor position in tiles ``u``, ``v``, its footprint ``wu``, ``wv``
    and how much of the checker shows there (``fade``: 0 off the floor), ``(H, W)`` each."""
    origins, directions = camera.rays()
    falling = directions[..., 2] < -1e-6
    reach = -origins[..., 2] / np.where(falling, directions[..., 2], -1.0)
    hits = origins[..., :2] + reach[..., None] * directions[..., :2]
    hits -= np.asarray(framing.target[:2])
    u, v = hits[..., 0] / tile, hits[..., 1] / tile
    wu = np.abs(np.gradient(u, axis=0)) + np.abs(np.gradient(u, axis=1))
    wv = np.abs(np.gradient(v, axis=0)) + np.abs(np.gradient(v, axis=1))
    radius = 1.6 * framing.distance * np.tan(np.radians(framing.fov) / 2) / tile
    near = np.exp(-(u**2 + v**2) / radius**2)
    sharp = np.clip(1.5 - 2.5 * np.maximum(wu, wv), 0.0, 1.0)
    return u, v, wu, wv, np.where(falling, near * sharp, 0.0)


class Backdrop:
    """Draw the sky and floor for one framing and image size; ``image`` per frame."""

    def __init__(self, framing: Framing, width: int, height: int, margin=(0, 0)):
        """``margin``: draw a canvas this many pixels (x, y; even) larger than the frame
        on every side, the frame at its centre (what :class:`rendering.framing.Shot` cuts
        a moving window from); the frame's own pixels are the same either way."""
        self.framing = framing
        self._tile = framing.height / 3
        across, down = (int(m) for m in margin)
        if across % 2 or down % 2:
            raise ValueError(f"a backdrop's margin must be even; got {margin!r}")
        camera = _grown(framing.camera(width, height), across, down)
        u, v, wu, wv, fade = _floor(camera, framing, self._tile)
        fade = fade[..., None]
        # The sky's gradient runs over the frame's own rows, whatever the margin.
        rows = np.pad(np.linspace(0.0, 1.0, height), down, mode="edge")[:, None, None]
        sky = palette.SKY_TOP * (1 - rows) + palette.SKY_HORIZON * rows

        # Only the rows where the tiles can change the picture by a quarter level are
        # redrawn per frame (the checker darkens by at most |FLOOR_DARK - FLOOR_LIGHT|),
        # through tables: of the box-filtered square wave, and of the darkening per
        # level of shade. A following camera redraws the floor every frame; this keeps it
        # to two table reads and a few operations per 2×2 block of floor (below).
        light = sky * (1 - fade) + palette.FLOOR_LIGHT * fade
        darker = palette.FLOOR_LIGHT - palette.FLOOR_DARK
        self._base = np.rint(light).astype(np.uint8)
        rows = np.flatnonzero((fade[..., 0] * darker.max() >= 0.25).any(axis=1))
        # The checker's darkening is worked out at half the size (each value for a 2×2
        # block, from the block's centre and footprint) and stretched: a quarter of the
        # table reads. It is box-filtered, so this only softens tile edges (against the
        # checker at full size: 0.1 grey level on average, at most 8 on an edge, at
        # 480x480). The band starts and ends on even rows.
        first, last = (int(rows.min()) // 2, (int(rows.max()) + 2) // 2) if len(rows) else (0, 0)
        self._rows = slice(2 * first, 2 * last)
        half = _grown(framing.camera(width // 2, height // 2), across // 2, down // 2)
        u, v, wu, wv, fade = _floor(half, framing, self._tile)
        band = np.s_[first:last]
        # Each floor pixel's place in the table: its footprint's row and its position's
        # column; a frame's shift of the camera then only moves where the table is read.
        self._index_u = _index(u[band], wu[band])
        self._index_v = _index(v[band], wv[band])
        self._half_fade = (fade[band] * (_SHADES / 2)).astype(np.float32)
        darkening = np.zeros((_SHADES + 1, 4), np.uint8)  # RGB and a spare byte per level
        darkening[:, :3] = np.rint(np.arange(_SHADES + 1)[:, None] / _SHADES * darker)
        self._darkening = darkening.view(np.uint32)[:, 0]
        self._still = None

    def image(self, target=None) -> np.ndarray:
        """Return a fresh backdrop ``(H, W, 3)`` uint8 with the look-at at ``target``."""
        if target is None or not self.framing.follow:
            if self._still is None:
                self._still = self._draw(0.0, 0.0)
            return self._still.copy()
        du = (target[0] - self.framing.target[0]) / self._tile
        dv = (target[1] - self.framing.target[1]) / self._tile
        return self._draw(du % 2.0, dv % 2.0)  # the checker repeats every two tiles

    def _draw(self, du: float, dv: float) -> np.ndarray:
        image = self._base.copy()
        if self._index_u.size:
            # checker * fade = (1 - wave_u * wave_v) * fade / 2, in place in one buffer.
            shade = _WAVE[_shift(du):].take(self._index_u)
            shade *= _WAVE[_shift(dv):].take(self._index_v)
            shade *= self._half_fade
            np.subtract(self._half_fade, shade, out=shade)
            # Each shade level's darkening is looked up as one 4-byte word (numpy gathers
            # words faster than three bytes a pixel), then the spare byte dropped.
            darkening = self._darkening.take(shade.astype(np.uint8))
            darkening = cv2.cvtColor(darkening.view(np.uint8).reshape(*shade.shape, 4),
                                     cv2.COLOR_RGBA2RGB)
            band = image[self._rows]
            cv2.subtract(band, cv2.resize(darkening, band.shape[1::-1],
                                          interpolation=cv2.INTER_LINEAR), dst=band)
        return image


def _grown(camera, across: int, down: int):
    """Return ``camera`` drawing a canvas ``across``, ``down`` pixels larger on each side."""
    if not across and not down:
        return camera
    return replace(camera, width=camera.width + 2 * across, height=camera.height + 2 * down)


_SHADES = 255  # levels of the checker's darkening, each a row of a table
_BINS = 256  # table columns per tile: positions to 1/256 of a tile
_PERIOD = 2 * _BINS  # the square wave repeats every two tiles
_WIDTHS = np.concatenate([[0.0], np.geomspace(1e-3, 4.0, 63)])  # footprints, in tiles


def _index(position: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Return each pixel's table index: its footprint's row, its position's column (bins).

    Rows hold two periods, so a shift of up to one period is a start further along.
    """
    index = np.clip(np.searchsorted(_WIDTHS, width), 1, len(_WIDTHS) - 1)
    nearer = np.where(width - _WIDTHS[index - 1] < _WIDTHS[index] - width, index - 1, index)
    column = np.floor(position * _BINS).astype(np.int64) % _PERIOD
    return (nearer * 2 * _PERIOD + column).astype(np.int32)


def _shift(tiles: float) -> int:
    """Return a shift of the camera, in tiles, as table columns (within one period)."""
    return int(np.floor(tiles * _BINS)) % _PERIOD


def _table() -> np.ndarray:
    """Return the box-filtered square wave, a row per footprint width (two periods long),
    a column per bin."""
    x = (np.arange(2 * _PERIOD) + 0.5) / _BINS
    widths = np.maximum(_WIDTHS, 1e-4)[:, None]
    return _square_wave_mean(x[None, :], widths).astype(np.float32).reshape(-1)


_WAVE = _table()

"""The scenery behind every figure: a soft sky and a checker floor fading into it."""

from __future__ import annotations

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


class Backdrop:
    """Draw the sky and floor for one framing and image size; ``image`` per frame."""

    def __init__(self, framing: Framing, width: int, height: int):
        self.framing = framing
        self._tile = framing.height / 3
        camera = framing.camera(width, height)
        origins, directions = camera.rays()
        falling = directions[..., 2] < -1e-6
        reach = -origins[..., 2] / np.where(falling, directions[..., 2], -1.0)
        hits = origins[..., :2] + reach[..., None] * directions[..., :2]
        hits -= np.asarray(framing.target[:2])
        u, v = hits[..., 0] / self._tile, hits[..., 1] / self._tile
        wu = np.abs(np.gradient(u, axis=0)) + np.abs(np.gradient(u, axis=1))
        wv = np.abs(np.gradient(v, axis=0)) + np.abs(np.gradient(v, axis=1))
        radius = 1.6 * framing.distance * np.tan(np.radians(framing.fov) / 2) / self._tile
        near = np.exp(-(u**2 + v**2) / radius**2)
        sharp = np.clip(1.5 - 2.5 * np.maximum(wu, wv), 0.0, 1.0)
        fade = np.where(falling, near * sharp, 0.0)[..., None]
        rows = np.linspace(0.0, 1.0, height)[:, None, None]
        sky = palette.SKY_TOP * (1 - rows) + palette.SKY_HORIZON * rows

        # Single precision, and all that does not move precomputed: a following camera
        # redraws the floor every frame.
        single = np.float32
        self._u, self._v = u.astype(single), v.astype(single)
        self._wu, self._wv = np.maximum(wu, 1e-4).astype(single), np.maximum(wv, 1e-4).astype(single)
        self._fade = fade[..., 0].astype(single)
        self._light = (sky * (1 - fade) + palette.FLOOR_LIGHT * fade).astype(single)
        self._darker = (palette.FLOOR_DARK - palette.FLOOR_LIGHT).astype(single)

    def image(self, target=None, box=None) -> np.ndarray:
        """Return the backdrop ``(H, W, 3)`` uint8 with the look-at at ``target``.

        ``box`` (left, top, right, bottom) draws only that part.
        """
        du = dv = 0.0
        if target is not None:
            du = (target[0] - self.framing.target[0]) / self._tile
            dv = (target[1] - self.framing.target[1]) / self._tile
        left, top, right, bottom = box or (0, 0, self._u.shape[1], self._u.shape[0])
        part = np.s_[top:bottom, left:right]
        u, v = self._u[part] + np.float32(du), self._v[part] + np.float32(dv)
        tiles = checker(u, v, self._wu[part], self._wv[part])
        image = self._light[part] + (tiles * self._fade[part])[..., None] * self._darker
        return np.rint(image).astype(np.uint8)

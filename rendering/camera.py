"""A pinhole or orthographic camera over a z-up world, projecting with numpy."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np


def view_direction(azimuth: float, elevation: float) -> np.ndarray:
    """Return the unit vector from the look-at point towards the eye (degrees, z up)."""
    az, el = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


@dataclass(frozen=True, eq=False)
class Camera:
    """Project world points ``(..., 3)`` to pixels; x right, y down, depth forward.

    ``rotation`` has the camera's right, down and forward axes as rows. For an
    orthographic camera ``focal`` is pixels per world unit, otherwise pixels at depth 1.
    """

    eye: np.ndarray
    rotation: np.ndarray
    focal: float
    width: int
    height: int
    orthographic: bool = False

    @classmethod
    def look_at(
        cls,
        target,
        azimuth: float,
        elevation: float,
        distance: float,
        fov: float,
        width: int,
        height: int,
        orthographic: bool = False,
    ) -> "Camera":
        """Place a camera ``distance`` from ``target``; ``fov`` is vertical, in degrees."""
        back = view_direction(azimuth, elevation)
        forward = -back
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        focal = height / 2 / math.tan(math.radians(fov) / 2)
        if orthographic:
            focal /= distance
        eye = np.asarray(target, dtype=np.float64) + distance * back
        return cls(eye, np.stack([right, down, forward]), focal, width, height, orthographic)

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """Return camera coordinates ``(..., 3)`` of world points ``(..., 3)``."""
        # einsum, not a matrix product: for a few joints BLAS's thread start-up costs far
        # more than the arithmetic, and on a busy machine it waits for its threads.
        return np.einsum("...j,ij->...i", np.asarray(points, dtype=np.float64) - self.eye,
                         self.rotation)

    def looking_at(self, shift) -> "Camera":
        """Return this camera moved by ``shift`` ``(3,)`` in the world, turned the same way."""
        return replace(self, eye=self.eye + np.asarray(shift, dtype=np.float64))

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return pixel coordinates ``(..., 2)`` and depths ``(...)`` of world points."""
        return self._on_image(self.to_camera(points))

    def project_each(self, points: np.ndarray, shifts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return :meth:`project` of each frame's points ``(T, N, 3)`` by this camera moved
        by that frame's ``shifts`` ``(T, 3)`` (:meth:`looking_at`), all frames at once."""
        eyes = self.eye + np.asarray(shifts, dtype=np.float64)
        return self._on_image(np.einsum("...j,ij->...i", np.asarray(points, dtype=np.float64)
                                        - eyes[:, None], self.rotation))

    def _on_image(self, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the pixels and depths of camera coordinates ``(..., 3)``."""
        depth = local[..., 2]
        scale = self.focal if self.orthographic else self.focal / np.maximum(depth, 1e-6)
        pixels = local[..., :2] * np.asarray(scale)[..., None]
        pixels[..., 0] += self.width / 2
        pixels[..., 1] += self.height / 2
        return pixels, depth

    def pixel_size(self, depth: np.ndarray) -> np.ndarray:
        """Return how many pixels one world unit spans at the given depths."""
        if self.orthographic:
            return np.full_like(np.asarray(depth, dtype=np.float64), self.focal)
        return self.focal / np.maximum(depth, 1e-6)

    def rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Return each pixel centre's ray origin and direction in world space, ``(H, W, 3)``."""
        xs = (np.arange(self.width) + 0.5 - self.width / 2) / self.focal
        ys = (np.arange(self.height) + 0.5 - self.height / 2) / self.focal
        grid_x, grid_y = np.meshgrid(xs, ys)
        right, down, forward = self.rotation
        if self.orthographic:
            origins = self.eye + grid_x[..., None] * right + grid_y[..., None] * down
            directions = np.broadcast_to(forward, origins.shape)
        else:
            directions = grid_x[..., None] * right + grid_y[..., None] * down + forward
            origins = np.broadcast_to(self.eye, directions.shape)
        return origins, directions

"""A body surface that came with the motion (SMPL vertices from an import), placed like its joints.

The framing places a clip's joints by one rigid move (turned about the vertical,
centred, stood on the floor); the same move, recovered from the joints before and
after, places the vertices, so the imported body stands exactly where its skeleton
does. It offers the interface of :class:`rendering.body.Body` that the mesh style uses.
"""

from __future__ import annotations

import hashlib

import numpy as np

from motion.motion import Motion
from motion.skeletons import Skeleton

SHADOW_POINTS = 320  # vertices standing in for the body in its floor shadow
SHADOW_RADIUS = 0.045  # their radius, per figure height


def rigid_move(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the rotation ``R`` and shift ``t`` with ``target ~ source @ R.T + t`` (Kabsch)."""
    source = source.reshape(-1, 3).astype(np.float64)
    target = target.reshape(-1, 3).astype(np.float64)
    source_mean, target_mean = source.mean(axis=0), target.mean(axis=0)
    u, _, vt = np.linalg.svd((source - source_mean).T @ (target - target_mean))
    flip = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rotation = vt.T @ np.diag([1.0, 1.0, flip]) @ u.T
    return rotation, target_mean - rotation @ source_mean


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Return unit normals ``(V, 3)``: the area-weighted mean of the faces around each vertex."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    face_normals = np.cross(b - a, c - a)
    normals = np.zeros_like(vertices)
    for k in range(3):
        for axis in range(3):
            normals[:, axis] += np.bincount(faces[:, k], face_normals[:, axis],
                                            minlength=len(vertices))
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.maximum(length, 1e-12)


class SurfaceBody:
    """The vertices ``(T, V, 3)`` and faces of a motion, moved onto its placed joints."""

    def __init__(self, skeleton: Skeleton, motion: Motion, placed: np.ndarray):
        self.skeleton = skeleton
        rotation, shift = rigid_move(motion.joints, placed)
        self.vertices = motion.vertices.astype(np.float64) @ rotation.T + shift
        self.faces = np.asarray(motion.faces, dtype=np.int64)
        self.n_vertices = self.vertices.shape[1]
        digest = hashlib.sha256(np.ascontiguousarray(self.faces).tobytes()).hexdigest()[:12]
        self.key = ("surface", self.n_vertices, digest)
        # Each vertex takes the side of the joint nearest to it in the first frame.
        nearest = np.argmin(np.linalg.norm(
            self.vertices[0][:, None] - placed[0][None].astype(np.float64), axis=-1), axis=1)
        sides = np.array([skeleton.side_of(j) for j in range(skeleton.n_joints)], dtype=object)
        self.sides = sides[nearest]
        heights = self.vertices[..., 2].max(axis=1) - self.vertices[..., 2].min(axis=1)
        self.unit = float(np.median(heights)) or 1.0
        step = max(1, self.n_vertices // SHADOW_POINTS)
        self._shadow = np.arange(0, self.n_vertices, step)

    def lift(self, height: float) -> None:
        """Raise the whole surface by ``height``."""
        self.vertices[..., 2] += height

    def pose_at(self, number: int, joints: np.ndarray):
        """Return frame ``number``'s vertices, normals, and shadow centres and radii."""
        vertices = self.vertices[number]
        centres = vertices[self._shadow]
        radii = np.full(len(centres), SHADOW_RADIUS * self.unit)
        return vertices, vertex_normals(vertices, self.faces), centres, radii

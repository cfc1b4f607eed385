"""Closed tubes swept along paths of moving points: the surface body parts are made of.

A tube follows a Catmull-Rom curve through its path points, so it bends smoothly where
it passes a joint; its cross-section is a (super)ellipse whose half-axes vary along the
path, and both ends close in rounded caps on one pole vertex each, so every tube is
watertight. The topology never changes and ring centres are linear in the points, so
posing all tubes of a body is a few matrix products per frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SEGMENTS = 16  # vertices around every ring


@dataclass(frozen=True)
class Tube:
    """One tube's shape in absolute units, before any pose.

    ``path`` names the points it runs through (two or more). ``profile`` lists
    ``(position, across, other)`` stations: the position along the path in segments
    (0 at the first point, ``len(path) - 1`` at the last), the half-axis along the
    ``across`` direction and the one square to it. ``across`` lists ``(position,
    vector)`` stations naming the direction the first half-axis follows, blended in
    between. ``caps`` are how far each end's cap reaches beyond its end point, and
    ``cap_rings`` how many rings round it (0 makes a cone: enough for an end hidden
    inside another part). ``exponent`` 2 makes ellipses, more makes boxier sections.
    """

    name: str
    side: str
    path: tuple[str, ...]
    profile: tuple[tuple[float, float, float], ...]
    across: tuple[tuple[float, str], ...]
    caps: tuple[float, float]
    rings: int = 6
    exponent: float = 2.0
    cap_rings: tuple[int, int] = (3, 3)


def smooth_interp(x: np.ndarray, xs, ys) -> np.ndarray:
    """Interpolate between stations with smoothstep weights (flat at every station)."""
    x = np.asarray(x, dtype=float)
    xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
    if len(xs) == 1:
        return np.full(x.shape, ys[0])
    index = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
    span = xs[index + 1] - xs[index]
    t = np.clip((x - xs[index]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    t = t * t * (3 - 2 * t)
    return ys[index] * (1 - t) + ys[index + 1] * t


def catmull_rom(count: int, position: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the weights of ``count`` path points for a curve's point and tangent.

    The path is extended by reflection at both ends (``P[-1] = 2 P[0] - P[1]``), so a
    two-point path is straight and the end tangents follow the end segments.
    """
    segment = min(int(np.floor(position)), count - 2)
    t = position - segment
    point = 0.5 * np.array([-t + 2 * t**2 - t**3, 2 - 5 * t**2 + 3 * t**3,
                            t + 4 * t**2 - 3 * t**3, -(t**2) + t**3])
    slope = 0.5 * np.array([-1 + 4 * t - 3 * t**2, -10 * t + 9 * t**2,
                            1 + 8 * t - 9 * t**2, -2 * t + 3 * t**2])
    weights = np.zeros((2, count))
    for offset in range(4):
        index = segment - 1 + offset
        if index < 0:
            spread = ((0, 2.0), (1, -1.0))
        elif index >= count:
            spread = ((count - 1, 2.0), (count - 2, -1.0))
        else:
            spread = ((index, 1.0),)
        for target, factor in spread:
            weights[0, target] += factor * point[offset]
            weights[1, target] += factor * slope[offset]
    return weights[0], weights[1]


class TubeSet:
    """Tubes posed together: ``pose(points, vectors)`` returns vertices and normals.

    ``points`` and ``vectors`` map the names used by the tubes to rows of the arrays
    later given to :meth:`pose`. Vertices are each tube's rings of ``SEGMENTS``, tube
    after tube, then two poles per tube.
    """

    def __init__(self, tubes: list[Tube], points: dict[str, int], vectors: dict[str, int]):
        self.tubes = list(tubes)
        rows = [self._rings(tube, points, vectors) for tube in self.tubes]
        self._place = np.concatenate([r["place"] for r in rows])
        self._slope = np.concatenate([r["slope"] for r in rows])
        self._across = np.concatenate([r["across"] for r in rows])
        self._reach = np.concatenate([r["reach"] for r in rows])
        self.half_a = np.concatenate([r["a"] for r in rows])
        self.half_b = np.concatenate([r["b"] for r in rows])
        self.owner = np.concatenate([np.full(len(r["a"]), k) for k, r in enumerate(rows)])
        ends = np.cumsum([len(r["a"]) for r in rows])
        self.ring_ranges = list(zip(np.concatenate([[0], ends[:-1]]).tolist(), ends.tolist()))
        self._first = np.array([start for start, _ in self.ring_ranges])
        self._last = np.array([end - 1 for _, end in self.ring_ranges])
        self._caps = np.array([tube.caps for tube in self.tubes], dtype=float)
        self._sections(np.concatenate([r["scale"] for r in rows]))
        self._neighbours()
        self._topology()

    @staticmethod
    def _rings(tube: Tube, points: dict[str, int], vectors: dict[str, int]) -> dict:
        """Return the constant rows of one tube's rings: weights, half-axes, cap reach."""
        count = len(tube.path)
        if count < 2:
            raise ValueError(f"tube {tube.name!r} needs at least two path points")
        body = np.linspace(0.0, count - 1, tube.rings * (count - 1) + 1)
        stations = [p[0] for p in tube.profile]
        a = smooth_interp(body, stations, [p[1] for p in tube.profile])
        b = smooth_interp(body, stations, [p[2] for p in tube.profile])
        # Cap rings go from the end ring towards the pole, at these angles past the equator.
        first, last = (np.linspace(0.0, np.pi / 2, n + 2)[1:-1] for n in tube.cap_rings)
        first = first[::-1]
        position = np.concatenate([np.zeros(len(first)), body, np.full(len(last), count - 1.0)])
        scale = np.concatenate([np.cos(first), np.ones(len(body)), np.cos(last)])
        reach = np.concatenate([-tube.caps[0] * np.sin(first), np.zeros(len(body)),
                                tube.caps[1] * np.sin(last)])
        a = np.concatenate([np.full(len(first), a[0]), a, np.full(len(last), a[-1])])
        b = np.concatenate([np.full(len(first), b[0]), b, np.full(len(last), b[-1])])

        columns = [points[name] for name in tube.path]
        place = np.zeros((len(position), len(points)))
        slope = np.zeros((len(position), len(points)))
        for row, where in enumerate(position):
            w_place, w_slope = catmull_rom(count, where)
            np.add.at(place[row], columns, w_place)
            np.add.at(slope[row], columns, w_slope)
        across = np.zeros((len(position), len(vectors)))
        stations = [s[0] for s in tube.across]
        for k, (_, name) in enumerate(tube.across):
            weight = smooth_interp(position, stations, np.eye(len(tube.across))[k])
            across[:, vectors[name]] += weight
        return {"place": place, "slope": slope, "across": across, "reach": reach,
                "a": a * scale, "b": b * scale, "scale": scale}

    def _sections(self, scale: np.ndarray) -> None:
        """Precompute each ring's cross-section points and in-plane normals."""
        angles = np.linspace(0.0, 2 * np.pi, SEGMENTS, endpoint=False)
        cos, sin = np.cos(angles), np.sin(angles)
        exponent = np.array([tube.exponent for tube in self.tubes])[self.owner][:, None]
        power = 2.0 / exponent
        self._u = self.half_a[:, None] * np.sign(cos) * np.abs(cos) ** power
        self._v = self.half_b[:, None] * np.sign(sin) * np.abs(sin) ** power
        # The normal of |x/a|^e + |y/b|^e = 1 at those points; a cap ring's scale
        # changes its size, not its shape.
        a = (self.half_a / scale)[:, None]
        b = (self.half_b / scale)[:, None]
        normal_u = np.sign(cos) * np.abs(cos) ** (2 - power) / a
        normal_v = np.sign(sin) * np.abs(sin) ** (2 - power) / b
        length = np.hypot(normal_u, normal_v)
        self._normal_u, self._normal_v = normal_u / length, normal_v / length
        self._radius = (self.half_a + self.half_b) / 2

    def _neighbours(self) -> None:
        """Index each ring's neighbours along its tube; the poles close the ends."""
        rings = len(self.half_a)
        self._ahead = np.minimum(np.arange(rings) + 1, rings - 1)
        self._behind = np.maximum(np.arange(rings) - 1, 0)
        self._at_end = np.zeros(rings, dtype=bool)
        self._at_start = np.zeros(rings, dtype=bool)
        self._at_end[self._last] = True
        self._at_start[self._first] = True

    def _topology(self) -> None:
        """Build the faces: quads between neighbouring rings, fans to the poles."""
        around = np.arange(SEGMENTS)
        turn = (around + 1) % SEGMENTS
        ring_vertices = len(self.half_a) * SEGMENTS
        faces, self.vertex_ranges = [], []
        for number, (start, end) in enumerate(self.ring_ranges):
            here = np.arange(start, end - 1)[:, None] * SEGMENTS
            there = here + SEGMENTS
            quads = np.concatenate([
                np.stack([here + around, here + turn, there + turn], axis=-1),
                np.stack([here + around, there + turn, there + around], axis=-1),
            ], axis=1)
            faces.append(quads.reshape(-1, 3))
            first_pole = ring_vertices + 2 * number
            first, last = start * SEGMENTS, (end - 1) * SEGMENTS
            start_pole, end_pole = np.full(SEGMENTS, first_pole), np.full(SEGMENTS, first_pole + 1)
            faces.append(np.stack([start_pole, first + turn, first + around], axis=1))
            faces.append(np.stack([end_pole, last + around, last + turn], axis=1))
            self.vertex_ranges.append((start * SEGMENTS, end * SEGMENTS, first_pole))
        self.faces = np.concatenate(faces).astype(np.int32)
        self.n_vertices = ring_vertices + 2 * len(self.tubes)

    def piece(self, number: int) -> tuple[np.ndarray, np.ndarray]:
        """Return the vertex indices and faces (into all vertices) of one tube."""
        start, end, pole = self.vertex_ranges[number]
        indices = np.concatenate([np.arange(start, end), [pole, pole + 1]])
        inside = np.isin(self.faces, indices).all(axis=1)
        return indices, self.faces[inside]

    def centres(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return each ring's centre and unit tangent, ``(R, 3)`` each."""
        tangents = self._slope @ points
        tangents /= np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-12)
        # Cap rings lie beyond their end point, along the end's tangent.
        return self._place @ points + self._reach[:, None] * tangents, tangents

    def pose(self, points: np.ndarray, vectors: np.ndarray):
        """Return vertices and unit normals ``(V, 3)``, ring centres and radii ``(R, ...)``.

        ``points`` ``(P, 3)`` are the path points and ``vectors`` ``(N, 3)`` the across
        directions, in the orders given to the constructor.
        """
        centres, tangents = self.centres(points)
        across = self._across @ vectors
        across -= np.sum(across * tangents, axis=1, keepdims=True) * tangents
        size = np.linalg.norm(across, axis=1, keepdims=True)
        if (size < 1e-9).any():  # an across direction along the tube: any square one will do
            axis = np.eye(3)[np.argmin(np.abs(tangents), axis=1)]
            across = np.where(size < 1e-9, np.cross(tangents, axis), across)
            size = np.linalg.norm(across, axis=1, keepdims=True)
        u = across / size
        v = np.cross(tangents, u)
        vertices = (centres[:, None, :] + self._u[..., None] * u[:, None, :]
                    + self._v[..., None] * v[:, None, :])

        poles = np.stack([
            centres[self._first] - (self._caps[:, 0] + self._reach[self._first])[:, None]
            * tangents[self._first],
            centres[self._last] + (self._caps[:, 1] - self._reach[self._last])[:, None]
            * tangents[self._last],
        ], axis=1)
        # Tilt the normals by how fast the tube narrows: (run, -rise) along the tube.
        ahead = np.where(self._at_end[:, None], poles[self.owner, 1], centres[self._ahead])
        behind = np.where(self._at_start[:, None], poles[self.owner, 0], centres[self._behind])
        rise = (np.where(self._at_end, 0.0, self._radius[self._ahead])
                - np.where(self._at_start, 0.0, self._radius[self._behind]))
        run = np.sum((ahead - behind) * tangents, axis=1)
        flat = self._normal_u[..., None] * u[:, None, :] + self._normal_v[..., None] * v[:, None, :]
        normals = flat * run[:, None, None] - rise[:, None, None] * tangents[:, None, :]
        normals /= np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-12)
        pole_normals = np.stack([-tangents[self._first], tangents[self._last]], axis=1)

        vertices = np.concatenate([vertices.reshape(-1, 3), poles.reshape(-1, 3)])
        normals = np.concatenate([normals.reshape(-1, 3), pole_normals.reshape(-1, 3)])
        return vertices, normals, centres, self._radius

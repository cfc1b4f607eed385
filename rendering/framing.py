"""One camera rule for a whole stimulus set, so clips differ in nothing but the motion.

Every clip is first *placed* in a z-up world the same way: turned so it starts facing
one direction, centred on its mean root position and stood on the floor (z = 0). The
camera then follows the rule: it looks at the smoothed body centre horizontally
(``follow``), from one angle, at one distance, so that a figure of the set's typical
height fills ``FILL`` of the frame's height with the floor under it at ``FLOOR_AT``. Only that
height comes from the motions, measured once on the set's real clips when it has any, so
no clip's own content (a jump, a jittered catch clip, a long walk) changes the scale.

Each clip is then filmed by a shot of the rule (``Framing.shot``) that keeps its figure
inside the frame for its whole length: the frame's window moves, smoothly and at the
same scale, over a canvas larger than the frame where the figure would reach an edge; a
still camera the figure outgrows follows it; only a figure larger than the frame on some
frame (a body flung apart) is filmed from farther away. Its content decides, never its
source.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from functools import lru_cache

import numpy as np

from motion.motion import Motion
from motion.skeletons import Skeleton, get_skeleton
from rendering.camera import Camera

# Rotations taking a skeleton's axes to z-up; all proper, so left stays left.
_TO_Z_UP = {
    "z": np.eye(3),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "-y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}
GROUNDS = ("clip", "set")
SHADOW_SLANT = 0.35  # how far a shadow falls sideways per unit of height
PAD = 0.07  # room kept around joints for the parts drawn on them, per figure height
# A standing figure (its drawn height: joints plus a style's pad) spans this share of the
# frame's height, its feet this far down the frame: room above for jumps and raised arms,
# below for the shadow, and a seated figure still fills about half the frame.
FILL = 0.70
FLOOR_AT = 0.88
GROUND_PERCENTILE = 10  # of per-frame lowest points: where a clip meets the floor
HEIGHT_PERCENTILE = 75  # of per-frame heights: a set's typical standing height
REAL = "real"
# A figure's box (its joints, plus a style's pad around each) is kept this share of the
# frame's height inside every edge; the window that keeps it there moves smoothly.
MARGIN = 0.015
# Free at the least beside a figure's box: in pixels (a video's colours bleed a pixel or
# two at low resolutions) and as a share of the frame's height (a larger box is zoomed out).
EDGE, EDGE_SHARE = 3.0, 0.005
SETTLE = 24  # rounds of smoothing and clamping the window's path (Framing.shot)
CANVAS_STEP = 16  # the canvas beyond the frame grows in these steps of pixels (even)
NEAR_SHARE = 0.05  # joints nearer the eye than this share of the distance are not drawn


def to_z_up(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Return joints ``(T, J, D)`` as ``(T, J, 3)`` with z up (2D: the x-z plane)."""
    joints = np.asarray(joints, dtype=np.float64)
    if skeleton.dims == 2:
        across = joints[..., 1 - skeleton.up_index]
        up = skeleton.up_sign * joints[..., skeleton.up_index]
        return np.stack([across, np.zeros_like(across), up], axis=-1)
    try:
        return joints @ _TO_Z_UP[skeleton.up].T
    except KeyError:
        raise ValueError(
            f"skeleton {skeleton.name!r} has an unsupported up axis {skeleton.up!r}"
        ) from None


def heading(joints: np.ndarray, skeleton: Skeleton) -> float | None:
    """Return the direction (degrees about z) a z-up pose ``(J, 3)`` faces, if it shows."""
    root = skeleton.root
    left = [j for j in skeleton.left if skeleton.parents[j] == root] or list(skeleton.left)
    right = [j for j in skeleton.right if skeleton.parents[j] == root] or list(skeleton.right)
    if not left or not right:
        return None
    across = joints[left].mean(axis=0) - joints[right].mean(axis=0)
    forward = np.cross(across, [0.0, 0.0, 1.0])
    if math.hypot(forward[0], forward[1]) < 1e-9:
        return None
    return math.degrees(math.atan2(forward[1], forward[0]))


@dataclass(frozen=True)
class Framing:
    """The camera and placement shared by every clip of a set (build with ``from_motions``).

    ``target`` is the look-at point (with ``follow``, relative to each frame's smoothed
    body centre, the mean of its joints), ``distance`` the eye's distance from it (for an orthographic view, the
    distance whose perspective view would show the same height), ``height`` the figures'
    typical height (sets the scale, limb thickness and floor tiles). ``facing`` turns
    each clip to start facing that direction (``None`` keeps it); ``ground`` is
    ``"clip"`` (each clip's lowest points on the floor; a tenth of its frames may reach
    below) or ``"set"`` (one floor, ``floor``, for all, so constant floating or sinking
    shows). ``follow`` moves the
    look-at with the smoothed body centre horizontally; without it the camera stays put.
    """

    dims: int
    target: tuple[float, float, float]
    distance: float
    height: float
    azimuth: float = -50.0
    elevation: float = 12.0
    fov: float = 35.0
    aspect: float = 1.0
    facing: float | None = -90.0
    recentre: bool = True
    ground: str = "clip"
    floor: float = 0.0
    follow: bool = True

    @classmethod
    def from_motions(
        cls,
        motions: list[Motion],
        *,
        aspect: float = 1.0,
        follow: bool = True,
        ground: str = "clip",
        pad: float = PAD,
        fill: float = FILL,
        **view,
    ) -> "Framing":
        """Fit the camera rule to a set of motions (all 3D or all 2D).

        Only the figures' typical height is measured, on the set's real clips when there
        are any (``source == "real"``), else on all. ``view`` may set ``azimuth``,
        ``elevation``, ``fov`` (degrees), ``facing`` and ``recentre``; ``pad`` is the room
        a style draws beyond the joints, per figure height (the drawn figure fills
        ``fill`` of the frame's height).
        """
        if not motions:
            raise ValueError("cannot frame an empty set of motions")
        dims = {get_skeleton(m.skeleton).dims for m in motions}
        if len(dims) != 1:
            raise ValueError("a set to frame together must be all 3D or all 2D motions")
        if ground not in GROUNDS:
            raise ValueError(f"ground must be one of {GROUNDS}; got {ground!r}")
        if not 0.0 < fill < FLOOR_AT:
            raise ValueError(f"fill must be between 0 and {FLOOR_AT}; got {fill!r}")
        dims = dims.pop()
        if dims == 2:
            view = {"azimuth": -90.0, "elevation": 0.0, "facing": None, **view}
        probe = cls(dims, (0.0,) * 3, 1.0, 1.0, aspect=aspect, ground=ground, follow=follow, **view)
        measured = [m for m in motions if m.source == REAL] or list(motions)
        floor = 0.0
        if ground == "set":
            floor = min(float(probe._placed_xy(m)[..., 2].min()) for m in measured)
        probe = probe._with(floor=floor)
        extents = []
        for motion in measured:
            placed = probe.place(motion)
            extents.append(placed[..., 2].max(axis=1) - placed[..., 2].min(axis=1))
        height = float(np.percentile(np.concatenate(extents), HEIGHT_PERCENTILE)) or 1.0
        distance, look_at = probe._with(height=height)._solve((1.0 + pad) * height, fill)
        start = (0.0, 0.0) if follow else tuple(probe._centre(measured))
        return probe._with(height=height, distance=distance, target=(*start, look_at))

    def _solve(self, drawn: float, fill: float) -> tuple[float, float]:
        """Return the distance and look-at height that put a pole of height ``drawn``,
        standing at the look-at, from ``FLOOR_AT`` up ``fill`` of the frame."""
        elevation = math.radians(self.elevation)
        across = 2 * math.tan(math.radians(self.fov) / 2)  # frame heights per unit depth

        def row(z, distance, look_at):  # where a point above the look-at shows, 0 = top
            rise = z - look_at
            depth = distance if self.orthographic else distance - rise * math.sin(elevation)
            return 0.5 - rise * math.cos(elevation) / (across * depth)

        def bisect(function, low, high):  # function increases from low to high
            for _ in range(60):
                middle = (low + high) / 2
                low, high = (middle, high) if function(middle) < 0 else (low, middle)
            return (low + high) / 2

        def aimed(distance):  # the look-at height that puts the foot at FLOOR_AT
            return bisect(lambda z: row(0.0, distance, z) - FLOOR_AT, -10 * drawn, drawn)

        def span(distance):  # grows with the distance
            look_at = aimed(distance)
            return fill - (row(0.0, distance, look_at) - row(drawn, distance, look_at))

        distance = bisect(span, 0.3 * drawn, 100.0 * drawn)
        return distance, aimed(distance)

    def _centre(self, motions: list[Motion]) -> np.ndarray:
        """Return the mean root position over a set's placed clips (a camera that stays)."""
        roots = [self.place(m)[:, get_skeleton(m.skeleton).root, :2] for m in motions]
        return np.concatenate(roots).mean(axis=0)

    def _with(self, **changes) -> "Framing":
        return type(self)(**{**asdict(self), **changes})

    def _axes(self) -> np.ndarray:
        """Return the camera's right, down and forward axes as rows."""
        return Camera.look_at((0, 0, 0), self.azimuth, self.elevation, 1.0, self.fov, 2, 2).rotation

    @property
    def orthographic(self) -> bool:
        return self.dims == 2

    def _placed_xy(self, motion: Motion) -> np.ndarray:
        """Return the joints z-up, turned and centred, but not yet stood on the floor."""
        skeleton = get_skeleton(motion.skeleton)
        joints = to_z_up(motion.joints, skeleton)
        if self.recentre:
            joints[..., :2] -= joints[:, skeleton.root, :2].mean(axis=0)
        if self.facing is not None and len(joints):
            start = heading(joints[0], skeleton)
            if start is not None:
                angle = math.radians(self.facing - start)
                cos, sin = math.cos(angle), math.sin(angle)
                turn = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
                joints = joints @ turn.T
        return joints

    def place(self, motion: Motion) -> np.ndarray:
        """Return the motion's joints as placed in this framing's world, ``(T, J, 3)``."""
        joints = self._placed_xy(motion)
        if self.ground == "clip" and joints.size:
            # The floor meets the clip's lowest points, not its single lowest: a glitch
            # in a few frames (a tenth) must not lift the whole clip off the floor.
            joints[..., 2] -= np.percentile(joints[..., 2].min(axis=1), GROUND_PERCENTILE)
        else:
            joints[..., 2] -= self.floor
        return joints

    def shadows(self, placed: np.ndarray) -> np.ndarray:
        """Return where placed points ``(..., 3)`` cast their shadows on the floor.

        The light is above, a little left of and behind the camera, so shadows fall
        right and towards the viewer, apart from the feet when these float.
        """
        return placed * [1.0, 1.0, 0.0] + placed[..., 2:3] * _shadow_fall(self)

    def targets(self, motion: Motion, placed: np.ndarray) -> np.ndarray:
        """Return the look-at point of each frame, ``(T, 3)``."""
        targets = np.tile(np.asarray(self.target, dtype=np.float64), (len(placed), 1))
        if self.follow and len(placed):
            # The body's centre (mean joint), not its hips: a seated figure's feet reach
            # far ahead of its hips, and would leave the frame's bottom.
            centre = placed[..., :2].mean(axis=1)
            window = max(1, int(round(motion.fps)))  # one second smooths the stride's sway
            # Odd reflection at the ends continues the centre's line, so the camera keeps
            # up with a steady walker to the last frame instead of lagging behind it.
            padding = ((window // 2, window - 1 - window // 2), (0, 0))
            padded = np.pad(centre, padding, mode="reflect", reflect_type="odd") \
                if len(centre) > 1 else np.pad(centre, padding, mode="edge")
            kernel = np.ones(window) / window
            targets[:, 0] += np.convolve(padded[:, 0], kernel, mode="valid")
            targets[:, 1] += np.convolve(padded[:, 1], kernel, mode="valid")
        return targets

    def shot(self, motion: Motion, width: int, height: int, pad=PAD,
             placed: np.ndarray | None = None) -> "Shot":
        """Return how a clip is filmed at ``width`` x ``height`` so that its figure stays
        inside the frame on every frame.

        The figure's box (its joints, ``pad`` of the figure height around each) is
        measured as the rule films it (:meth:`targets`). Where it would reach within
        ``MARGIN`` of an edge, the frame's window moves over a canvas larger than the
        frame (a shift of the lens: the same camera, the same scale), along a path
        smoothed over one second and clamped so the box never leaves. Only a clip whose
        box on one frame is larger than the frame (a body flung apart, never a standing
        or walking one) is filmed from farther away, just far enough: its content alone
        decides, never its source. A still camera (``follow`` off) stays still unless
        the figure on some frame is larger than the frame (it walks up to the eye); that
        clip's camera follows it. ``pad`` is a share of the figure height, or one per
        joint; ``placed`` is the motion as :meth:`place` returns it.
        """
        placed = self.place(motion) if placed is None else placed
        size = np.array([width, height], dtype=np.float64)
        least_keep = max(EDGE, EDGE_SHARE * height)  # free on each side at the least
        room = size - 2 * least_keep
        framing = self
        if not self.follow:
            low, high = self._boxes(placed, self.targets(motion, placed), width, height, pad)
            if len(low) and ((high - low).max(axis=0) > room).any():
                # A still camera the figure outgrows (it walks up to or past the eye):
                # the camera follows this clip instead, at the same scale.
                framing = self._with(follow=True, target=(0.0, 0.0, self.target[2]))
        for _ in range(8):
            targets = framing.targets(motion, placed)
            low, high = framing._boxes(placed, targets, width, height, pad)
            spread = (high - low).max(axis=0) if len(low) else np.zeros(2)
            if (spread <= room).all():
                break
            # Zoomed out (the look-at keeps its place): a last resort, see the docstring.
            zoom = max(1.02, float((spread / room).max()))
            framing = framing._with(distance=framing.distance * zoom)
        # The window's corner, per frame: keeping MARGIN (at least EDGE pixels) free where
        # the box leaves room, else the least; a frame larger still (never after zooming)
        # is centred.
        keep = max(EDGE, MARGIN * height)
        least, most = high - (size - keep), low - keep
        edges = least > most
        least = np.where(edges, high - (size - least_keep), least)
        most = np.where(edges, low - least_keep, most)
        middle = (least + most) / 2
        tight = least > most
        least, most = np.where(tight, middle, least), np.where(tight, middle, most)
        path = np.clip(0.0, least, most)
        window = max(1, int(round(motion.fps)))
        for _ in range(SETTLE if path.any() else 0):
            path = np.clip(_smooth(path, window), least, most)
        low_int, high_int = np.ceil(least), np.floor(most)
        stuck = low_int > high_int
        low_int = np.where(stuck, np.rint(middle), low_int)
        high_int = np.where(stuck, np.rint(middle), high_int)
        offsets = np.clip(np.rint(path), low_int, high_int).astype(int).reshape(-1, 2)
        reach = np.abs(offsets).max(axis=0) if len(offsets) else np.zeros(2, int)
        margin = tuple(int(-(-r // CANVAS_STEP) * CANVAS_STEP) for r in reach)
        return Shot(framing, targets, offsets, margin)

    def _boxes(self, placed: np.ndarray, targets: np.ndarray, width: int, height: int,
               pad: float) -> tuple[np.ndarray, np.ndarray]:
        """Return each frame's figure box in pixels, its top-left and bottom-right ``(T, 2)``
        (joints with ``pad`` of the figure height around each; a frame showing nothing:
        the frame's centre)."""
        camera = self.camera(width, height)
        pixels, depth = camera.project_each(placed, targets - np.asarray(self.target))
        seen = depth > NEAR_SHARE * self.distance
        reach = (np.asarray(pad) * self.height * camera.pixel_size(depth))[..., None]
        low = np.where(seen[..., None], pixels - reach, np.inf).min(axis=1)
        high = np.where(seen[..., None], pixels + reach, -np.inf).max(axis=1)
        centre = np.array([width / 2, height / 2])
        shown = seen.any(axis=1)[:, None]
        return np.where(shown, low, centre), np.where(shown, high, centre)

    def camera(self, width: int, height: int, target=None) -> Camera:
        """Return the camera for an image of this size looking at ``target`` (default: ours)."""
        camera = _base_camera(self, width, height)
        if target is None:
            return camera
        return camera.looking_at(np.asarray(target, dtype=np.float64) - self.target)

    def as_dict(self) -> dict:
        """Return the framing as plain data (for the researcher's sidecar)."""
        return asdict(self)


def _smooth(path: np.ndarray, window: int) -> np.ndarray:
    """Return a path ``(T, 2)`` averaged over ``window`` frames (its ends continued in
    their line, as :meth:`Framing.targets` does)."""
    if window <= 1 or len(path) < 2:
        return path
    padding = ((window // 2, window - 1 - window // 2), (0, 0))
    padded = np.pad(path, padding, mode="reflect", reflect_type="odd")
    kernel = np.ones(window) / window
    return np.stack([np.convolve(padded[:, k], kernel, mode="valid")
                     for k in range(path.shape[1])], axis=1)


@dataclass(frozen=True, eq=False)
class Shot:
    """How one clip is filmed (:meth:`Framing.shot`): its ``framing`` (the set's, or
    farther away as a last resort), the look-at of each frame, and the frame's window on
    each frame: ``offsets`` ``(T, 2)`` pixels moved right and down from where the rule
    puts it, over a canvas ``margin`` (x, y) pixels larger than the frame on every side."""

    framing: Framing
    targets: np.ndarray
    offsets: np.ndarray
    margin: tuple[int, int] = (0, 0)

    def canvas(self, width: int, height: int) -> tuple[int, int]:
        """Return the size of the canvas a frame of ``width`` x ``height`` is cut from."""
        return width + 2 * self.margin[0], height + 2 * self.margin[1]

    def camera(self, width: int, height: int, target=None) -> Camera:
        """Return the camera drawing the canvas of a frame of this size (at ``target``)."""
        camera = self.framing.camera(width, height, target)
        if self.margin == (0, 0):
            return camera
        return replace(camera, width=camera.width + 2 * self.margin[0],
                       height=camera.height + 2 * self.margin[1])

    def cut(self, canvas: np.ndarray, number: int, width: int, height: int) -> np.ndarray:
        """Return frame ``number``: its window of the canvas drawn for it."""
        if self.margin == (0, 0):
            return canvas
        left = self.margin[0] + int(self.offsets[number, 0])
        top = self.margin[1] + int(self.offsets[number, 1])
        return np.ascontiguousarray(canvas[top:top + height, left:left + width])


@lru_cache(maxsize=64)
def _base_camera(framing: Framing, width: int, height: int) -> Camera:
    """Return a framing's camera at its own look-at (made once: clips move it per frame)."""
    return Camera.look_at(framing.target, framing.azimuth, framing.elevation, framing.distance,
                          framing.fov, width, height, orthographic=framing.orthographic)


@lru_cache(maxsize=64)
def _shadow_fall(framing: Framing) -> np.ndarray:
    """Return how far a shadow falls per unit of height (made once: every frame asks)."""
    right, _, forward = framing._axes()
    fall = 0.8 * right[:2] - 0.6 * forward[:2]
    fall = np.append(fall / np.linalg.norm(fall) * SHADOW_SLANT, 0.0)
    fall.flags.writeable = False
    return fall

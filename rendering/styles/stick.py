"""Stick figures: shaded tubes and balls in perspective over a floor with a soft shadow.

Drawn with OpenCV at the frame's own size, anti-aliased at 1/16 pixel (tubes as filled
quadrilaterals, balls as 16-gons), far to near, over the backdrop drawn once at the
frame's size (the floor is box-filtered, so it needs no extra samples); the shadow is
drawn at half the size, blurred and stretched. An order of magnitude faster than
matplotlib 3D or pyrender.
"""

from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np

from motion.motion import Motion
from motion.skeletons import Skeleton, get_skeleton
from rendering import palette
from rendering.backdrop import Backdrop
from rendering.camera import Camera
from rendering.framing import Framing
from rendering.styles.base import Style, register_style

SHADOW_SHRINK = 2  # the shadow is drawn this much smaller, then blurred and stretched
# The shadow's blur, at the least, in pixels of its half-size map: drawn anti-aliased and
# blurred by at least this, it has no stair-stepped 2x2 blocks in small frames.
SHADOW_BLUR_LEAST = 0.8
LIGHT = np.array([-0.55, -0.83])  # on screen: from the upper left
NEAR = 0.05  # parts nearer the eye than this share of the camera distance are not drawn
CHUNK = 16  # frames whose geometry is worked out together
# OpenCV takes coordinates and radii as integers in 1/2**SHIFT pixel; its pixel centres
# lie on whole numbers, the camera's half a pixel further (Camera.rays).
SHIFT = 4
ONE = 1 << SHIFT
CENTRE = 0.5
# OpenCV's anti-aliased edge reaches beyond a shape by about 0.65 pixel: drawn this much
# smaller, tubes (bands 2-20 pixels wide) and balls (16-gons of radius 2.2-20) cover
# their true area within 6 % (measured at random angles and sub-pixel positions).
BLEED = 0.65
# Balls are drawn as polygons of this many corners, of the disc's area (OpenCV's own
# anti-aliased circles have 4 corners below a radius of 3 pixels, 12 below 10).
CORNERS = 16
_ANGLES = np.arange(CORNERS) * 2 * np.pi / CORNERS
_POLYGON = np.stack([np.cos(_ANGLES), np.sin(_ANGLES)], axis=-1) * np.sqrt(
    np.pi / (CORNERS / 2 * np.sin(2 * np.pi / CORNERS)))
# Shapes reaching farther than this beyond the frame are clipped to it before drawing
# (OpenCV's integers must not overflow); what lies out there shows nothing.
GUARD = 1 << 12
# Shadow lines are clipped by OpenCV; their ends are only kept within its integers.
LINE_REACH = 1 << 22

# Sizes as fractions of the figure height, the same for every clip of a set.
BONE_RADIUS = 0.021
JOINT_RADIUS = 0.029
HEAD_RADIUS = 0.062
# Each tube is three bands (rim, body, highlight) of these widths, each ball three
# discs of these radii, as shares of the part's radius.
BANDS = np.array([1.0, 0.72, 0.25])
DISCS = np.array([1.0, 0.76, 0.3])


class Figure:
    """What to draw for one skeleton: its bones, and each part's colour and radius."""

    def __init__(self, skeleton: Skeleton, height: float):
        self.bones = np.array(skeleton.bones, dtype=int).reshape(-1, 2)
        sides = [skeleton.side_of(j) for j in range(skeleton.n_joints)]
        self.joint_colours = np.array([palette.side_colour(s) for s in sides])
        self.bone_colours = self.joint_colours[self.bones[:, 1]]
        self.bone_radius = BONE_RADIUS * height
        self.joint_radii = np.full(skeleton.n_joints, JOINT_RADIUS * height)
        children = {p for p in skeleton.parents if p >= 0}
        for joint, name in enumerate(skeleton.joint_names):
            if "head" in name.lower() and joint not in children:
                self.joint_radii[joint] = HEAD_RADIUS * height


def _tones(colours: np.ndarray) -> np.ndarray:
    """Return the (rim, body, highlight) colours ``(..., 3, 3)`` of base colours ``(..., 3)``."""
    shades = np.stack([colours * 0.66, colours, colours + (palette.WHITE - colours) * 0.5],
                      axis=-2)
    return np.rint(shades).astype(np.uint8)


def _fixed(points: np.ndarray, low=-LINE_REACH, high=LINE_REACH) -> np.ndarray:
    """Return pixel coordinates (camera convention) as OpenCV's fixed-point integers,
    held within ``[low, high]``."""
    points = points - CENTRE
    np.clip(points, np.asarray(low, points.dtype), np.asarray(high, points.dtype), out=points)
    points *= ONE
    return np.rint(points, out=points).astype(np.int32)


def _clip(polygon: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Return a convex polygon ``(N, 2)`` cut to the box ``[low, high]`` (Sutherland-Hodgman);
    it stays convex, and may come out empty."""
    for axis in (0, 1):
        for bound, inside in ((low[axis], np.greater_equal), (high[axis], np.less_equal)):
            if not len(polygon):
                return polygon
            kept = []
            for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
                a_in, b_in = inside(a[axis], bound), inside(b[axis], bound)
                if a_in:
                    kept.append(a)
                if a_in != b_in:
                    kept.append(a + (b - a) * (bound - a[axis]) / (b[axis] - a[axis]))
            polygon = np.array(kept).reshape(-1, 2)
    return polygon


def _shapes(polygons: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, dict]:
    """Return polygons ``(..., N, 2)`` in pixels as fixed-point integers, and those that
    reach beyond the guard around a frame of ``size`` cut to it, by index (rare)."""
    low = np.array([-GUARD, -GUARD], dtype=float)
    high = np.array(size, dtype=float) + GUARD
    beyond = ((polygons < low) | (polygons > high)).any(axis=(-1, -2))
    cut = {index: _fixed(_clip(polygons[index], low, high))
           for index in zip(*np.nonzero(beyond))}
    return _fixed(polygons, low - CENTRE, high - CENTRE), cut


def _darken(frame: np.ndarray, shadow) -> None:
    """Lay the shadow colour over ``frame`` through a mask ``(mask (h, w) uint8, (left, top))``.

    Each pixel moves towards the shadow colour by the mask's share (``mask / 255``); the
    backdrop is lighter than the shadow colour everywhere, so all in unsigned bytes.
    """
    if shadow is None:
        return
    mask, (left, top) = shadow
    height, width = frame.shape[:2]
    right, bottom = min(left + mask.shape[1], width), min(top + mask.shape[0], height)
    if right <= left or bottom <= top:
        return
    part = frame[top:bottom, left:right]
    weight = cv2.cvtColor(mask[: bottom - top, : right - left], cv2.COLOR_GRAY2RGB)
    above = cv2.subtract(part, _SHADOW_INK)
    cv2.subtract(part, cv2.multiply(above, weight, scale=1 / 255), dst=part)


_SHADOW_INK = (*palette.SHADOW, 0)


@register_style("stick")
class StickStyle(Style):
    """Skeletons in 3D: warm left, cool right, neutral centre, on a checker floor."""

    dims = 3
    shadow = True
    player_figure = "stick"

    def __init__(self, framing: Framing, width: int, height: int):
        super().__init__(framing, width, height)
        self._backdrop = Backdrop(framing, width, height)
        self._backdrops = {(framing, (0, 0)): self._backdrop}
        self._figures: dict[str, Figure] = {}

    def frames(self, motion: Motion) -> Iterator[np.ndarray]:
        figure = self._figure(motion.skeleton)
        placed = self.framing.place(motion)
        shot = self.framing.shot(motion, self.width, self.height, self.reach(motion.skeleton),
                                 placed)
        backdrop = self._backdrop_of(shot)
        for begin in range(0, len(placed), CHUNK):
            yield from self._chunk(figure, placed[begin:begin + CHUNK], shot, begin, backdrop)

    def _backdrop_of(self, shot) -> Backdrop:
        """Return the backdrop of a shot's framing and canvas (the set's own is kept)."""
        key = (shot.framing, shot.margin)
        if key not in self._backdrops:
            if len(self._backdrops) > 4:  # a clip needing a larger canvas is rare
                for old in list(self._backdrops)[1:]:
                    del self._backdrops[old]
            self._backdrops[key] = Backdrop(shot.framing, self.width, self.height, shot.margin)
        return self._backdrops[key]

    def _chunk(self, figure: Figure, placed: np.ndarray, shot, begin: int, backdrop: Backdrop):
        """Yield the frames of consecutive poses ``(T, J, 3)`` of a shot from frame ``begin``."""
        # The geometry of a chunk's frames at once: numpy's cost per call, not its
        # arithmetic, dominates arrays of a few joints, so only the drawing calls are
        # left per frame (and memory does not grow with the clip's length).
        framing = shot.framing
        targets = shot.targets[begin:begin + len(placed)]
        camera = shot.camera(self.width, self.height)  # at the framing's own look-at
        size = (camera.width, camera.height)  # the canvas the frame is cut from
        shifts = targets - np.asarray(framing.target, dtype=np.float64)
        pixels, depth = camera.project_each(placed, shifts)
        drawing = self._figure_plan(pixels, depth, camera.pixel_size(depth), figure, framing,
                                    size)
        shadows = (self._shadow_plan(camera, shifts, placed, figure, framing, size)
                   if self.shadow else None)
        for number, target in enumerate(targets):
            frame = backdrop.image(target)
            if shadows is not None:
                _darken(frame, self._shadow(shadows, number))
            self._draw_figure(frame, drawing, number)
            yield shot.cut(frame, begin + number, self.width, self.height)

    def reach(self, skeleton: str) -> np.ndarray:
        """Return each joint's ball radius per figure height (bones are thinner)."""
        return self._figure(skeleton).joint_radii / self.framing.height

    def _figure(self, skeleton: str) -> Figure:
        if skeleton not in self._figures:
            self._figures[skeleton] = Figure(get_skeleton(skeleton), self.framing.height)
        return self._figures[skeleton]

    def _shadow_plan(self, camera: Camera, shifts, placed: np.ndarray, figure: Figure,
                     framing: Framing, canvas: tuple[int, int]) -> dict:
        """Return the shadow's geometry for every frame (see :meth:`_shadow`) on a canvas
        of size ``canvas``."""
        pixels, depth = camera.project_each(framing.shadows(placed), shifts)
        seen = depth > NEAR * framing.distance
        pixels /= SHADOW_SHRINK
        reach = camera.pixel_size(depth) / SHADOW_SHRINK
        unit = framing.height * float(camera.pixel_size(framing.distance)) / SHADOW_SHRINK
        closeness = 1.0 - np.clip(placed[..., 2] / (0.2 * framing.height), 0.0, 1.0)
        strength = np.where(seen, 100.0, 0.0)  # nothing of what lies at or behind the eye
        reach = np.where(seen, reach, 0.0)

        blurred = 4 * max(SHADOW_BLUR_LEAST, 0.012 * unit)  # the blur's reach
        border = (1.4 * figure.joint_radii * reach + blurred + 2)[..., None]
        size = (canvas[0] // SHADOW_SHRINK, canvas[1] // SHADOW_SHRINK)
        any_seen = seen.any(axis=1)
        low = np.where(seen[..., None], pixels - border, np.inf).min(axis=1)
        high = np.where(seen[..., None], pixels + border, -np.inf).max(axis=1)
        low = np.maximum(np.floor(np.where(any_seen[:, None], low, 0.0)), 0).astype(int)
        high = np.minimum(np.ceil(np.where(any_seen[:, None], high, 0.0)), size).astype(int)
        pixels = np.where(seen[..., None], pixels, low[:, None])  # unseen parts at no size
        pixels = pixels - low[:, None]
        a, b = figure.bones[:, 0], figure.bones[:, 1]
        bone_reach = (reach[:, a] + reach[:, b]) / 2
        ends = np.stack([pixels[:, a], pixels[:, b]], axis=-2)  # (T, bones, 2, 2)
        limit = (high - low)[:, None]
        layers = []
        for layer_strength, spread, blur in (
                (strength, 1.4, 0.012), (np.where(seen, closeness**2 * 150, 0.0), 1.2, 0.006)):
            # Each layer is drawn and blurred only in its own box (its discs, the blur's
            # reach and a margin), as plain numbers per frame for OpenCV.
            sigma = max(SHADOW_BLUR_LEAST, blur * unit)
            order = np.argsort(layer_strength, axis=1, kind="stable")  # the strongest on top
            strength_ordered = np.take_along_axis(layer_strength, order, axis=1)
            discs = strength_ordered >= 1
            radii = spread * figure.joint_radii[order] * np.take_along_axis(reach, order, axis=1)
            centres = np.take_along_axis(pixels, order[..., None], axis=1)
            levels = np.minimum(layer_strength[:, a], layer_strength[:, b]).astype(int)
            drawn = levels > 0  # the joints' wider discs cover the ends
            widths = np.maximum(1, np.rint(2 * spread * figure.bone_radius * bone_reach))
            margin = np.ceil(4 * sigma) + 4 + np.where(drawn, widths, 0).max(axis=1)
            margin = margin[:, None]
            corner = np.where(discs[..., None], centres - radii[..., None], np.inf).min(axis=1)
            far = np.where(discs[..., None], centres + radii[..., None], -np.inf).max(axis=1)
            corner = np.maximum(np.floor(np.where(discs.any(axis=1)[:, None], corner - margin,
                                                  0.0)), 0).astype(int)
            far = np.minimum(np.ceil(np.where(discs.any(axis=1)[:, None], far + margin, 0.0)),
                             limit[:, 0]).astype(int)
            layers.append({
                "sigma": sigma, "corner": corner, "far": far,
                "boxed": discs.any(axis=1) & (far > corner).all(axis=1),
                "lines": _fixed(ends - corner[:, None, None]), "widths": widths.astype(int),
                "levels": levels, "drawn": drawn,
                "centres": _fixed(centres - corner[:, None]), "discs": discs,
                "radii": np.rint(radii * ONE).astype(np.int32),
                "strength": strength_ordered.astype(int),
            })
        return {"low": low, "high": high, "layers": layers,
                "valid": any_seen & (high > low).all(axis=1)}

    def _shadow(self, plan: dict, number: int):
        """Return frame ``number``'s shadow mask and its top-left corner in the frame, or ``None``.

        A faint shadow of the whole figure, plus a darker one where parts are near the
        floor: contact, sliding and floating all show against it. It is drawn small,
        blurred and stretched, and only over the patch it covers.
        """
        if not plan["valid"][number]:
            return None
        low, high = plan["low"][number], plan["high"][number]
        mask = None
        for layer in plan["layers"]:
            # Blurring zeros gives zeros, so drawing a layer only in its box changes nothing.
            if not layer["boxed"][number]:
                continue
            (left, top), (right, bottom) = layer["corner"][number], layer["far"][number]
            layer_image = np.zeros((bottom - top, right - left), np.uint8)
            for (start, end), level, width, drawn in zip(
                    layer["lines"][number].tolist(), layer["levels"][number].tolist(),
                    layer["widths"][number].tolist(), layer["drawn"][number].tolist()):
                if drawn:
                    cv2.line(layer_image, start, end, level, width, cv2.LINE_AA, SHIFT)
            for centre, radius, level, disc in zip(
                    layer["centres"][number].tolist(), layer["radii"][number].tolist(),
                    layer["strength"][number].tolist(), layer["discs"][number].tolist()):
                if disc:
                    cv2.circle(layer_image, centre, radius, level, -1, cv2.LINE_AA, SHIFT)
            layer_image = cv2.GaussianBlur(layer_image, (0, 0), layer["sigma"])
            if mask is None:
                mask = np.zeros(tuple(high - low)[::-1], np.uint8)
            box = mask[top:bottom, left:right]
            cv2.add(box, layer_image, dst=box)
        if mask is None:
            return None
        mask = cv2.resize(mask, (mask.shape[1] * SHADOW_SHRINK, mask.shape[0] * SHADOW_SHRINK),
                          interpolation=cv2.INTER_LINEAR)
        return mask, tuple(int(v) * SHADOW_SHRINK for v in low)

    def _figure_plan(self, pixels, depth, reach, figure: Figure, framing: Framing,
                     canvas: tuple[int, int]) -> dict:
        """Return every frame's bones and joints as tubes and balls lit from the upper
        left, far to near, as plain numbers for OpenCV's drawing (see
        :meth:`_draw_figure`); ``pixels`` ``(T, J, 2)`` on a canvas of size ``canvas``."""
        bones = figure.bones
        head, tail = bones[:, 0], bones[:, 1]
        start, end = pixels[:, head], pixels[:, tail]
        bone_depth = (depth[:, head] + depth[:, tail]) / 2
        bone_radii = figure.bone_radius * (reach[:, head] + reach[:, tail]) / 2
        joint_radii = figure.joint_radii * reach

        # Nearer parts a little brighter, farther ones fading towards the sky.
        tone = np.concatenate([bone_depth, depth], axis=1) - framing.distance
        tone = np.clip(tone / framing.height, -1.0, 1.0)
        base = np.concatenate([figure.bone_colours, figure.joint_colours])
        base = base * (1.0 - 0.1 * tone[..., None])
        base = base + (palette.SKY_HORIZON - base) * (0.25 * np.maximum(tone, 0.0))[..., None]
        tones = _tones(np.clip(base, 0.0, 255.0))

        along = end - start
        length = np.linalg.norm(along, axis=-1, keepdims=True)
        normal = np.stack([-along[..., 1], along[..., 0]], axis=-1) / np.maximum(length, 1e-6)
        lit = (normal * LIGHT).sum(axis=-1)
        light_offset = normal * lit[..., None]  # the light's component across the tube

        # Each band is a quadrilateral: the bone's ends moved towards the light, widened
        # across the bone (no round caps: every bone ends in a joint's larger ball,
        # drawn nearer).
        # (In single precision: a chunk's quadrilaterals are the style's largest array.)
        r = bone_radii[..., None, None]
        moved = light_offset[..., None, :] * (r * np.array([0.0, 0.2, 0.48])[:, None])
        across = (normal[..., None, :] * np.maximum(r * BANDS[:, None] - BLEED, 0.0)
                  ).astype(np.float32)
        head_end = (start[..., None, :] + moved).astype(np.float32)
        tail_end = (end[..., None, :] + moved).astype(np.float32)
        quads = np.stack([head_end + across, tail_end + across, tail_end - across,
                          head_end - across], axis=-2)  # (T, bones, 3, 4, 2)
        j = joint_radii[..., None]
        centres = np.stack([pixels, pixels + LIGHT * 0.2 * j, pixels + LIGHT * 0.45 * j], axis=-2)

        near = NEAR * framing.distance
        seen = np.concatenate([(depth[:, head] > near) & (depth[:, tail] > near), depth > near],
                              axis=1)
        # Balls sit a little nearer than the tubes meeting at them, so they cap the ends.
        order = np.argsort(-np.concatenate([bone_depth, depth - figure.joint_radii], axis=1),
                           axis=1, kind="stable")
        quads, cut_quads = _shapes(quads, canvas)
        # Balls become polygons frame by frame (a chunk's would be the style's largest array).
        return {"quads": quads, "cut_quads": cut_quads, "centres": centres,
                "radii": np.maximum(j * DISCS - BLEED, 0.0), "tones": tones, "order": order,
                "seen": seen, "bones": len(bones), "canvas": canvas}

    def _draw_figure(self, frame: np.ndarray, plan: dict, number: int):
        """Draw frame ``number``'s bones and joints far to near (:meth:`_figure_plan`)."""
        quads = plan["quads"][number]
        cut_quads = {key[1:]: shape for key, shape in plan["cut_quads"].items()
                     if key[0] == number}
        radii = plan["radii"][number][..., None, None]
        balls, cut_balls = _shapes(plan["centres"][number][..., None, :] + radii * _POLYGON,
                                   plan["canvas"])
        tones = plan["tones"][number].tolist()
        order, seen, n_bones = plan["order"][number], plan["seen"][number], plan["bones"]
        for k in order[seen[order]].tolist():
            shapes, part, cut = ((quads, k, cut_quads) if k < n_bones
                                 else (balls, k - n_bones, cut_balls))
            for layer, (shape, tone) in enumerate(zip(shapes[part], tones[k])):
                if cut:  # a shape reaching far beyond the frame: drawn as cut to the guard
                    shape = cut.get((part, layer), shape)
                    if not len(shape):
                        continue
                cv2.fillConvexPoly(frame, shape, tone, cv2.LINE_AA, SHIFT)

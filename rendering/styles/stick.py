"""Stick figures: shaded tubes and balls in perspective over a floor with a soft shadow.

Drawn with Pillow far to near, at twice the size and halved (4 samples a pixel), and
only around the figure, over the backdrop drawn once at the frame's size (the floor is
box-filtered, so it needs no extra samples); an order of magnitude faster than
matplotlib 3D or pyrender.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from PIL import Image, ImageChops, ImageDraw, ImageFilter

from generation.motion import Motion
from generation.skeletons import Skeleton, get_skeleton
from rendering import palette
from rendering.backdrop import Backdrop
from rendering.camera import Camera
from rendering.framing import Framing
from rendering.styles.base import Style, register_style

SUPERSAMPLE = 2
SHADOW_SHRINK = 4  # the shadow is drawn this much smaller, then blurred and stretched
LIGHT = np.array([-0.55, -0.83])  # on screen: from the upper left
NEAR = 0.05  # parts nearer the eye than this share of the camera distance are not drawn

# Sizes as fractions of the figure height, the same for every clip of a set.
BONE_RADIUS = 0.021
JOINT_RADIUS = 0.029
HEAD_RADIUS = 0.062


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


def _tones(colours: np.ndarray) -> list[list[tuple[int, int, int]]]:
    """Return the (rim, body, highlight) colours of each base colour ``(N, 3)``."""
    shades = np.stack([colours * 0.66, colours, colours + (palette.WHITE - colours) * 0.5], axis=1)
    return [[tuple(tone) for tone in part] for part in np.rint(shades).astype(int).tolist()]


def _disc(draw: ImageDraw.ImageDraw, centre, radius: float, fill) -> None:
    x, y = centre
    draw.ellipse((x - radius, y - radius, x + radius, y + radius), fill=fill)


def _tube(draw: ImageDraw.ImageDraw, start, end, radius: float, fill, capped=True) -> None:
    draw.line((start[0], start[1], end[0], end[1]), fill=fill, width=max(1, int(round(2 * radius))))
    if capped:
        _disc(draw, start, radius, fill)
        _disc(draw, end, radius, fill)


def _cover(pixels, radii, size) -> tuple[int, int, int, int] | None:
    """Return the even-aligned box around the figure, inside the image."""
    low = (pixels - radii[:, None]).min(axis=0) - 4
    high = (pixels + radii[:, None]).max(axis=0) + 4
    step = SUPERSAMPLE
    left, top = (max(0, int(np.floor(v / step)) * step) for v in low)
    right, bottom = (min(limit, int(np.ceil(v / step)) * step) for v, limit in zip(high, size))
    if right <= left or bottom <= top:
        return None
    return left, top, right, bottom


def _darken(frame: np.ndarray, shadow) -> None:
    """Lay the shadow colour over ``frame`` through a mask ``(mask, (left, top))``."""
    if shadow is None:
        return
    mask, (left, top) = shadow
    height, width = frame.shape[:2]
    right, bottom = min(left + mask.shape[1], width), min(top + mask.shape[0], height)
    if right <= left or bottom <= top:
        return
    alpha = mask[: bottom - top, : right - left, None].astype(np.uint16)
    part = frame[top:bottom, left:right]
    mixed = part * (255 - alpha) + np.array(palette.SHADOW, np.uint16) * alpha + 127
    part[...] = (mixed // 255).astype(np.uint8)


@register_style("stick")
class StickStyle(Style):
    """Skeletons in 3D: warm left, cool right, neutral centre, on a checker floor."""

    dims = 3
    shadow = True

    def __init__(self, framing: Framing, width: int, height: int):
        super().__init__(framing, width, height)
        self._size = (width * SUPERSAMPLE, height * SUPERSAMPLE)
        self._backdrop = Backdrop(framing, width, height)
        self._figures: dict[str, Figure] = {}

    def frames(self, motion: Motion) -> Iterator[np.ndarray]:
        figure = self._figure(motion.skeleton)
        placed = self.framing.place(motion)
        targets = self.framing.targets(motion, placed)
        for pose, target in zip(placed, targets):
            camera = self.framing.camera(*self._size, target)
            pixels, depth = camera.project(pose)
            frame = self._backdrop.image(target)
            if self.shadow:
                _darken(frame, self._shadow(camera, pose, figure))
            # Only the patch around the figure is drawn large and halved.
            seen = depth > NEAR * self.framing.distance  # a joint flung at or behind the eye
            box = _cover(pixels[seen], (figure.joint_radii * camera.pixel_size(depth))[seen],
                         self._size) if seen.any() else None
            if box is None:
                yield frame
                continue
            left, top, right, bottom = (v // SUPERSAMPLE for v in box)
            part = Image.fromarray(frame[top:bottom, left:right])
            patch = part.resize((part.width * SUPERSAMPLE, part.height * SUPERSAMPLE),
                                Image.NEAREST)
            origin = np.array(box[:2], dtype=float)
            self._draw_figure(ImageDraw.Draw(patch), pixels - origin, depth, camera, figure)
            frame[top:bottom, left:right] = np.asarray(patch.reduce(SUPERSAMPLE))
            yield frame

    def _figure(self, skeleton: str) -> Figure:
        if skeleton not in self._figures:
            self._figures[skeleton] = Figure(get_skeleton(skeleton), self.framing.height)
        return self._figures[skeleton]

    def _shadow(self, camera: Camera, pose: np.ndarray, figure: Figure):
        """Return the shadow's mask and its top-left corner in the frame, or ``None``.

        A faint shadow of the whole figure, plus a darker one where parts are near the
        floor: contact, sliding and floating all show against it. It is drawn small,
        blurred and stretched, and only over the patch it covers.
        """
        pixels, depth = camera.project(self.framing.shadows(pose))
        seen = depth > NEAR * self.framing.distance
        if not seen.any():
            return None
        pixels /= SHADOW_SHRINK
        reach = camera.pixel_size(depth) / SHADOW_SHRINK
        unit = self.framing.height * float(camera.pixel_size(self.framing.distance)) / SHADOW_SHRINK
        closeness = 1.0 - np.clip(pose[:, 2] / (0.2 * self.framing.height), 0.0, 1.0)
        strength = np.where(seen, 100.0, 0.0)  # nothing of what lies at or behind the eye
        layers = ((strength, 1.4, 0.012), (np.where(seen, closeness**2 * 150, 0.0), 1.2, 0.006))
        reach = np.where(seen, reach, 0.0)

        border = (1.4 * figure.joint_radii * reach + 3 * 0.012 * unit + 2)[seen, None]
        size = (self._size[0] // SHADOW_SHRINK, self._size[1] // SHADOW_SHRINK)
        low = np.maximum(np.floor((pixels[seen] - border).min(axis=0)), 0).astype(int)
        high = np.minimum(np.ceil((pixels[seen] + border).max(axis=0)), size).astype(int)
        pixels = np.where(seen[:, None], pixels, low)  # unseen parts are drawn at no size
        if (high <= low).any():
            return None
        pixels = pixels - low
        a, b = figure.bones[:, 0], figure.bones[:, 1]
        bone_reach = (reach[a] + reach[b]) / 2
        masks = []
        for strength, spread, blur in layers:
            mask = Image.new("L", tuple(high - low), 0)
            draw = ImageDraw.Draw(mask)
            levels = np.minimum(strength[a], strength[b]).astype(int)
            radii = spread * figure.bone_radius * bone_reach
            for start, end, radius, level in zip(pixels[a].tolist(), pixels[b].tolist(),
                                                 radii.tolist(), levels.tolist()):
                if level > 0:  # the joints' wider discs cover the ends
                    _tube(draw, start, end, radius, level, capped=False)
            order = np.argsort(strength)
            radii = spread * figure.joint_radii[order] * reach[order]
            for centre, radius, level in zip(pixels[order].tolist(), radii.tolist(),
                                             strength[order].tolist()):
                if level >= 1:
                    _disc(draw, centre, radius, int(level))
            masks.append(mask.filter(ImageFilter.GaussianBlur(max(0.5, blur * unit))))
        mask = ImageChops.add(*masks)
        grow = SHADOW_SHRINK // SUPERSAMPLE  # to the frame's own size
        mask = mask.resize((mask.width * grow, mask.height * grow), Image.BILINEAR)
        return np.asarray(mask), tuple(int(v) * grow for v in low)

    def _draw_figure(self, draw: ImageDraw.ImageDraw, pixels, depth, camera: Camera, figure):
        """Draw bones and joints far to near, each a tube or ball lit from the upper left."""
        reach = camera.pixel_size(depth)
        bones = figure.bones
        start, end = pixels[bones[:, 0]], pixels[bones[:, 1]]
        bone_depth = (depth[bones[:, 0]] + depth[bones[:, 1]]) / 2
        bone_radii = figure.bone_radius * (reach[bones[:, 0]] + reach[bones[:, 1]]) / 2
        joint_radii = figure.joint_radii * reach

        # Nearer parts a little brighter, farther ones fading towards the sky.
        tone = np.concatenate([bone_depth, depth]) - self.framing.distance
        tone = np.clip(tone / self.framing.height, -1.0, 1.0)
        base = np.concatenate([figure.bone_colours, figure.joint_colours])
        base = base * (1.0 - 0.1 * tone[:, None])
        base = base + (palette.SKY_HORIZON - base) * (0.25 * np.maximum(tone, 0.0))[:, None]
        base = np.clip(base, 0.0, 255.0)
        tones = _tones(base)

        along = end - start
        length = np.linalg.norm(along, axis=1, keepdims=True)
        normal = np.stack([-along[:, 1], along[:, 0]], axis=1) / np.maximum(length, 1e-6)
        lit = (normal * LIGHT).sum(axis=1)
        light_offset = normal * lit[:, None]  # the light's component across the tube

        # Every primitive's place and size at once, as plain floats for Pillow.
        r = bone_radii[:, None]
        body_shift, shine = light_offset * 0.2 * r, light_offset * 0.48 * r
        bones_drawn = np.concatenate(
            [start, end, start + body_shift, end + body_shift, start + shine, end + shine, r,
             0.72 * r, 0.25 * r], axis=1).tolist()
        j = joint_radii[:, None]
        joints_drawn = np.concatenate(
            [pixels, pixels + LIGHT * 0.2 * j, pixels + LIGHT * 0.45 * j, j, 0.76 * j, 0.3 * j],
            axis=1).tolist()

        n_bones = len(bones)
        near = NEAR * self.framing.distance
        seen = np.concatenate([(depth[bones[:, 0]] > near) & (depth[bones[:, 1]] > near),
                               depth > near])
        # Balls sit a little nearer than the tubes meeting at them, so they cap the ends.
        order = np.argsort(-np.concatenate([bone_depth, depth - figure.joint_radii]), kind="stable")
        for k in order[seen[order]].tolist():
            rim, body, highlight = tones[k]
            if k < n_bones:
                (x0, y0, x1, y1, bx0, by0, bx1, by1, hx0, hy0, hx1, hy1,
                 radius, body_radius, shine_radius) = bones_drawn[k]
                # No round caps: every bone ends in a joint's larger ball, drawn nearer.
                _tube(draw, (x0, y0), (x1, y1), radius, rim, capped=False)
                _tube(draw, (bx0, by0), (bx1, by1), body_radius, body, capped=False)
                _tube(draw, (hx0, hy0), (hx1, hy1), shine_radius, highlight, capped=False)
            else:
                x, y, bx, by, hx, hy, radius, body_radius, shine_radius = joints_drawn[k - n_bones]
                _disc(draw, (x, y), radius, rim)
                _disc(draw, (bx, by), body_radius, body)
                _disc(draw, (hx, hy), shine_radius, highlight)

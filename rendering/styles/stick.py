"""Stick figures: shaded tubes and balls in perspective over a floor with a soft shadow.

Drawn with Pillow far to near, at twice the size and halved (4 samples a pixel), and
only around the figure; an order of magnitude faster than matplotlib 3D or pyrender.
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


def _tube(draw: ImageDraw.ImageDraw, start, end, radius: float, fill) -> None:
    draw.line((start[0], start[1], end[0], end[1]), fill=fill, width=max(1, int(round(2 * radius))))
    _disc(draw, start, radius, fill)
    _disc(draw, end, radius, fill)


def _cover(pixels, radii, shadow, size) -> tuple[int, int, int, int] | None:
    """Return the even-aligned box around the figure and its shadow, inside the image."""
    low = (pixels - radii[:, None]).min(axis=0) - 4
    high = (pixels + radii[:, None]).max(axis=0) + 4
    if shadow is not None:
        mask, corner = shadow
        low = np.minimum(low, corner)
        high = np.maximum(high, (corner[0] + mask.width, corner[1] + mask.height))
    step = SUPERSAMPLE
    left, top = (max(0, int(np.floor(v / step)) * step) for v in low)
    right, bottom = (min(limit, int(np.ceil(v / step)) * step) for v, limit in zip(high, size))
    if right <= left or bottom <= top:
        return None
    return left, top, right, bottom


@register_style("stick")
class StickStyle(Style):
    """Skeletons in 3D: warm left, cool right, neutral centre, on a checker floor."""

    dims = 3
    shadow = True

    def __init__(self, framing: Framing, width: int, height: int):
        super().__init__(framing, width, height)
        self._size = (width * SUPERSAMPLE, height * SUPERSAMPLE)
        self._backdrop = Backdrop(framing, *self._size)
        self._small_backdrop = Backdrop(framing, width, height) if framing.follow else None
        self._still = None
        self._figures: dict[str, Figure] = {}

    def frames(self, motion: Motion) -> Iterator[np.ndarray]:
        figure = self._figure(motion.skeleton)
        placed = self.framing.place(motion)
        targets = self.framing.targets(motion, placed)
        for pose, target in zip(placed, targets):
            camera = self.framing.camera(*self._size, target)
            pixels, depth = camera.project(pose)
            shadow = self._shadow(camera, pose, figure) if self.shadow else None
            # Only the patch around the figure and its shadow is drawn large and halved.
            box = _cover(pixels, figure.joint_radii * camera.pixel_size(depth), shadow, self._size)
            patch, frame = self._scenery(target, box)
            if box is None:
                yield np.asarray(frame)
                continue
            origin = np.array(box[:2], dtype=float)
            if shadow is not None:
                mask, corner = shadow
                patch.paste(palette.SHADOW, (corner[0] - box[0], corner[1] - box[1]), mask)
            self._draw_figure(ImageDraw.Draw(patch), pixels - origin, depth, camera, figure)
            frame.paste(patch.reduce(SUPERSAMPLE), (box[0] // SUPERSAMPLE, box[1] // SUPERSAMPLE))
            yield np.asarray(frame)

    def _figure(self, skeleton: str) -> Figure:
        if skeleton not in self._figures:
            self._figures[skeleton] = Figure(get_skeleton(skeleton), self.framing.height)
        return self._figures[skeleton]

    def _scenery(self, target, box) -> tuple[Image.Image | None, Image.Image]:
        """Return the backdrop's patch inside ``box`` drawn large, and a fresh whole frame."""
        if self.framing.follow:
            patch = Image.fromarray(self._backdrop.image(target, box)) if box else None
            return patch, Image.fromarray(self._small_backdrop.image(target))
        if self._still is None:
            large = Image.fromarray(self._backdrop.image())
            self._still = (large, large.reduce(SUPERSAMPLE))
        large, small = self._still
        return (large.crop(box) if box else None), small.copy()

    def _shadow(self, camera: Camera, pose: np.ndarray, figure: Figure):
        """Return the shadow's mask and its top-left corner in the large image, or ``None``.

        A faint shadow of the whole figure, plus a darker one where parts are near the
        floor: contact, sliding and floating all show against it. It is drawn small,
        blurred and stretched, and only over the patch it covers.
        """
        pixels, depth = camera.project(self.framing.shadows(pose))
        pixels /= SHADOW_SHRINK
        reach = camera.pixel_size(depth) / SHADOW_SHRINK
        unit = self.framing.height * float(camera.pixel_size(self.framing.distance)) / SHADOW_SHRINK
        closeness = 1.0 - np.clip(pose[:, 2] / (0.2 * self.framing.height), 0.0, 1.0)
        layers = ((np.full(len(pose), 100.0), 1.4, 0.012), (closeness**2 * 150, 1.2, 0.006))

        border = 1.4 * figure.joint_radii * reach + 3 * 0.012 * unit + 2
        size = (self._size[0] // SHADOW_SHRINK, self._size[1] // SHADOW_SHRINK)
        low = np.maximum(np.floor((pixels - border[:, None]).min(axis=0)), 0).astype(int)
        high = np.minimum(np.ceil((pixels + border[:, None]).max(axis=0)), size).astype(int)
        if (high <= low).any():
            return None
        pixels = pixels - low
        bone_reach = (reach[figure.bones[:, 0]] + reach[figure.bones[:, 1]]) / 2
        masks = []
        for strength, spread, blur in layers:
            mask = Image.new("L", tuple(high - low), 0)
            draw = ImageDraw.Draw(mask)
            for (a, b), bone_scale in zip(figure.bones, bone_reach):
                level = int(min(strength[a], strength[b]))
                if level > 0:
                    radius = spread * figure.bone_radius * bone_scale
                    _tube(draw, pixels[a], pixels[b], radius, level)
            for j in np.argsort(strength):
                if strength[j] >= 1:
                    radius = spread * figure.joint_radii[j] * reach[j]
                    _disc(draw, pixels[j], radius, int(strength[j]))
            masks.append(mask.filter(ImageFilter.GaussianBlur(max(0.5, blur * unit))))
        mask = ImageChops.add(*masks)
        stretched = (mask.width * SHADOW_SHRINK, mask.height * SHADOW_SHRINK)
        return mask.resize(stretched, Image.BILINEAR), tuple(int(v) * SHADOW_SHRINK for v in low)

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
        lit = normal @ LIGHT
        light_offset = normal * lit[:, None]  # the light's component across the tube

        n_bones = len(bones)
        # Balls sit a little nearer than the tubes meeting at them, so they cap the ends.
        order = np.argsort(-np.concatenate([bone_depth, depth - figure.joint_radii]), kind="stable")
        for k in order:
            rim, body, highlight = tones[k]
            if k < n_bones:
                r, shift = bone_radii[k], light_offset[k]
                _tube(draw, start[k], end[k], r, rim)
                _tube(draw, start[k] + shift * 0.2 * r, end[k] + shift * 0.2 * r, 0.72 * r, body)
                shine = shift * 0.48 * r
                _tube(draw, start[k] + shine, end[k] + shine, 0.25 * r, highlight)
            else:
                j = k - n_bones
                r, centre = joint_radii[j], pixels[j]
                _disc(draw, centre, r, rim)
                _disc(draw, centre + LIGHT * 0.2 * r, 0.76 * r, body)
                _disc(draw, centre + LIGHT * 0.45 * r, 0.3 * r, highlight)

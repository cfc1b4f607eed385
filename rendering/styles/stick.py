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
CHUNK = 16  # frames whose geometry is worked out together

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


def _tones(colours: np.ndarray) -> np.ndarray:
    """Return the (rim, body, highlight) colours ``(..., 3, 3)`` of base colours ``(..., 3)``."""
    shades = np.stack([colours * 0.66, colours, colours + (palette.WHITE - colours) * 0.5],
                      axis=-2)
    return np.rint(shades).astype(int)


def _inks(tones: np.ndarray) -> np.ndarray:
    """Return Pillow's inks for RGB colours ``(..., 3)``: the packed pixel, opaque."""
    packed = tones[..., 0] | tones[..., 1] << 8 | tones[..., 2] << 16 | 255 << 24
    return packed.astype(np.uint32).view(np.int32)


def _covers(pixels, radii, seen, size) -> tuple[np.ndarray, np.ndarray]:
    """Return each frame's even-aligned box around the figure, inside the image, and
    whether it has one: ``(T, 4)`` (left, top, right, bottom) and ``(T,)``."""
    wide = radii[..., None]
    any_seen = seen.any(axis=1)
    low = np.where(seen[..., None], pixels - wide, np.inf).min(axis=1) - 4
    high = np.where(seen[..., None], pixels + wide, -np.inf).max(axis=1) + 4
    low = np.where(any_seen[:, None], low, 0.0)  # frames with nothing seen: no box
    high = np.where(any_seen[:, None], high, 0.0)
    step = SUPERSAMPLE
    corner = np.maximum(0, np.floor(low / step).astype(int) * step)
    far = np.minimum(size, np.ceil(high / step).astype(int) * step)
    return np.concatenate([corner, far], axis=1), any_seen & (far > corner).all(axis=1)


def _darken(frame: np.ndarray, shadow) -> None:
    """Lay the shadow colour over ``frame`` through a mask ``(mask image, (left, top))``."""
    if shadow is None:
        return
    mask, (left, top) = shadow
    height, width = frame.shape[:2]
    right, bottom = min(left + mask.width, width), min(top + mask.height, height)
    if right <= left or bottom <= top:
        return
    part = Image.fromarray(frame[top:bottom, left:right])
    part.paste(palette.SHADOW, (0, 0, right - left, bottom - top),
               mask.crop((0, 0, right - left, bottom - top)))
    frame[top:bottom, left:right] = np.asarray(part)


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
        for begin in range(0, len(placed), CHUNK):
            yield from self._chunk(figure, placed[begin:begin + CHUNK],
                                   targets[begin:begin + CHUNK])

    def _chunk(self, figure: Figure, placed: np.ndarray, targets: np.ndarray):
        """Yield the frames of consecutive poses ``(T, J, 3)`` with their look-at points."""
        # The geometry of a chunk's frames at once: numpy's cost per call, not its
        # arithmetic, dominates arrays of a few joints, so only Pillow's drawing is left
        # per frame (and memory does not grow with the clip's length).
        camera = self.framing.camera(*self._size)  # at the framing's own look-at
        shifts = targets - np.asarray(self.framing.target, dtype=np.float64)
        pixels, depth = camera.project_each(placed, shifts)
        seen = depth > NEAR * self.framing.distance  # a joint flung at or behind the eye
        reach = camera.pixel_size(depth)
        boxes, boxed = _covers(pixels, figure.joint_radii * reach, seen, self._size)
        # Drawn on the patch of each box: coordinates from the patch's corner.
        local = pixels - boxes[:, None, :2].astype(float)
        drawing = self._figure_plan(local, depth, reach, figure)
        shadows = self._shadow_plan(camera, shifts, placed, figure) if self.shadow else None
        for number, target in enumerate(targets):
            frame = self._backdrop.image(target)
            if shadows is not None:
                _darken(frame, self._shadow(shadows, number))
            if not boxed[number]:
                yield frame
                continue
            # Only the patch around the figure is drawn large and halved.
            left, top, right, bottom = (int(v) // SUPERSAMPLE for v in boxes[number])
            part = Image.fromarray(frame[top:bottom, left:right])
            patch = part.resize((part.width * SUPERSAMPLE, part.height * SUPERSAMPLE),
                                Image.NEAREST)
            self._draw_figure(ImageDraw.Draw(patch), drawing, number)
            frame[top:bottom, left:right] = np.asarray(patch.reduce(SUPERSAMPLE))
            yield frame

    def _figure(self, skeleton: str) -> Figure:
        if skeleton not in self._figures:
            self._figures[skeleton] = Figure(get_skeleton(skeleton), self.framing.height)
        return self._figures[skeleton]

    def _shadow_plan(self, camera: Camera, shifts, placed: np.ndarray, figure: Figure) -> dict:
        """Return the shadow's geometry for every frame (see :meth:`_shadow`)."""
        pixels, depth = camera.project_each(self.framing.shadows(placed), shifts)
        seen = depth > NEAR * self.framing.distance
        pixels /= SHADOW_SHRINK
        reach = camera.pixel_size(depth) / SHADOW_SHRINK
        unit = self.framing.height * float(camera.pixel_size(self.framing.distance)) / SHADOW_SHRINK
        closeness = 1.0 - np.clip(placed[..., 2] / (0.2 * self.framing.height), 0.0, 1.0)
        strength = np.where(seen, 100.0, 0.0)  # nothing of what lies at or behind the eye
        reach = np.where(seen, reach, 0.0)

        border = (1.4 * figure.joint_radii * reach + 3 * 0.012 * unit + 2)[..., None]
        size = (self._size[0] // SHADOW_SHRINK, self._size[1] // SHADOW_SHRINK)
        any_seen = seen.any(axis=1)
        low = np.where(seen[..., None], pixels - border, np.inf).min(axis=1)
        high = np.where(seen[..., None], pixels + border, -np.inf).max(axis=1)
        low = np.maximum(np.floor(np.where(any_seen[:, None], low, 0.0)), 0).astype(int)
        high = np.minimum(np.ceil(np.where(any_seen[:, None], high, 0.0)), size).astype(int)
        pixels = np.where(seen[..., None], pixels, low[:, None])  # unseen parts at no size
        pixels = pixels - low[:, None]
        a, b = figure.bones[:, 0], figure.bones[:, 1]
        bone_reach = (reach[:, a] + reach[:, b]) / 2
        lines = np.concatenate([pixels[:, a], pixels[:, b]], axis=-1)
        layers = []
        for layer_strength, spread, blur in (
                (strength, 1.4, 0.012), (np.where(seen, closeness**2 * 150, 0.0), 1.2, 0.006)):
            levels = np.minimum(layer_strength[:, a], layer_strength[:, b]).astype(int)
            widths = np.maximum(1, np.rint(2 * spread * figure.bone_radius * bone_reach))
            layers.append({
                "strength": layer_strength, "spread": spread, "sigma": max(0.5, blur * unit),
                "levels": levels, "drawn": levels > 0,  # the joints' wider discs cover the ends
                "order": np.argsort(layer_strength, axis=1), "widths": widths,
            })
        return {"pixels": pixels, "reach": reach, "low": low, "high": high, "lines": lines,
                "valid": any_seen & (high > low).all(axis=1), "layers": layers,
                "radii": figure.joint_radii}

    def _shadow(self, plan: dict, number: int):
        """Return frame ``number``'s shadow mask and its top-left corner in the frame, or ``None``.

        A faint shadow of the whole figure, plus a darker one where parts are near the
        floor: contact, sliding and floating all show against it. It is drawn small,
        blurred and stretched, and only over the patch it covers.
        """
        if not plan["valid"][number]:
            return None
        pixels, reach = plan["pixels"][number], plan["reach"][number]
        low, high = plan["low"][number], plan["high"][number]
        lines_all = plan["lines"][number]
        mask = None
        for layer in plan["layers"]:
            # Each layer is drawn and blurred only where it has anything: the darker one
            # often only around the feet. Blurring zeros gives zeros, so the box (the
            # parts, the blur's reach and a margin) changes nothing.
            strength, order = layer["strength"][number], layer["order"][number]
            order = order[strength[order] >= 1]
            if not len(order):
                continue
            drawn, sigma = layer["drawn"][number], layer["sigma"]
            radii = (layer["spread"] * plan["radii"][order] * reach[order])[:, None]
            discs = np.concatenate([pixels[order] - radii, pixels[order] + radii], axis=1)
            widths = layer["widths"][number][drawn]
            lines = lines_all[drawn]
            margin = np.ceil(4 * sigma) + 4 + (widths.max() if len(widths) else 0)
            corner = np.maximum(np.floor(discs[:, :2].min(axis=0) - margin), 0).astype(int)
            far = np.minimum(np.ceil(discs[:, 2:].max(axis=0) + margin), high - low).astype(int)
            if (far <= corner).any():
                continue
            layer_image = Image.new("L", tuple(far - corner), 0)
            core = ImageDraw.Draw(layer_image).draw
            shift = np.tile(corner, 2)
            for line, level, width in zip((lines - shift).tolist(),
                                          layer["levels"][number][drawn].tolist(),
                                          widths.astype(int).tolist()):
                core.draw_lines(line, level, width)
            for disc, level in zip((discs - shift).tolist(), strength[order].astype(int).tolist()):
                core.draw_ellipse(disc, level, 1)
            layer_image = layer_image.filter(ImageFilter.GaussianBlur(sigma))
            if mask is None:
                mask = Image.new("L", tuple(high - low), 0)
            box = (*corner.tolist(), *far.tolist())
            mask.paste(ImageChops.add(mask.crop(box), layer_image), box)
        if mask is None:
            return None
        grow = SHADOW_SHRINK // SUPERSAMPLE  # to the frame's own size
        mask = mask.resize((mask.width * grow, mask.height * grow), Image.BILINEAR)
        return mask, tuple(int(v) * grow for v in low)

    def _figure_plan(self, pixels, depth, reach, figure: Figure) -> dict:
        """Return every frame's bones and joints as tubes and balls lit from the upper
        left, far to near, as plain numbers for Pillow's drawing core (see
        :meth:`_draw_figure`); ``pixels`` ``(T, J, 2)`` on each frame's patch."""
        bones = figure.bones
        head, tail = bones[:, 0], bones[:, 1]
        start, end = pixels[:, head], pixels[:, tail]
        bone_depth = (depth[:, head] + depth[:, tail]) / 2
        bone_radii = figure.bone_radius * (reach[:, head] + reach[:, tail]) / 2
        joint_radii = figure.joint_radii * reach

        # Nearer parts a little brighter, farther ones fading towards the sky.
        tone = np.concatenate([bone_depth, depth], axis=1) - self.framing.distance
        tone = np.clip(tone / self.framing.height, -1.0, 1.0)
        base = np.concatenate([figure.bone_colours, figure.joint_colours])
        base = base * (1.0 - 0.1 * tone[..., None])
        base = base + (palette.SKY_HORIZON - base) * (0.25 * np.maximum(tone, 0.0))[..., None]
        tones = _tones(np.clip(base, 0.0, 255.0))

        along = end - start
        length = np.linalg.norm(along, axis=-1, keepdims=True)
        normal = np.stack([-along[..., 1], along[..., 0]], axis=-1) / np.maximum(length, 1e-6)
        lit = (normal * LIGHT).sum(axis=-1)
        light_offset = normal * lit[..., None]  # the light's component across the tube

        r = bone_radii[..., None]
        body_shift, shine = light_offset * 0.2 * r, light_offset * 0.48 * r
        lines = np.concatenate([start, end, start + body_shift, end + body_shift, start + shine,
                                end + shine], axis=-1).reshape(*start.shape[:2], 3, 4)
        widths = np.maximum(1, np.rint(2 * r * [1.0, 0.72, 0.25])).astype(int)
        j = joint_radii[..., None]
        centres = np.stack([pixels, pixels + LIGHT * 0.2 * j, pixels + LIGHT * 0.45 * j], axis=-2)
        radii = (j * [1.0, 0.76, 0.3])[..., None]
        discs = np.concatenate([centres - radii, centres + radii], axis=-1)

        near = NEAR * self.framing.distance
        seen = np.concatenate([(depth[:, head] > near) & (depth[:, tail] > near), depth > near],
                              axis=1)
        # Balls sit a little nearer than the tubes meeting at them, so they cap the ends.
        order = np.argsort(-np.concatenate([bone_depth, depth - figure.joint_radii], axis=1),
                           axis=1, kind="stable")
        return {"lines": lines, "widths": widths, "discs": discs, "inks": _inks(tones),
                "order": order, "seen": seen, "bones": len(bones)}

    def _draw_figure(self, draw: ImageDraw.ImageDraw, plan: dict, number: int):
        """Draw frame ``number``'s bones and joints far to near (:meth:`_figure_plan`)."""
        lines, widths = plan["lines"][number].tolist(), plan["widths"][number].tolist()
        discs, inks = plan["discs"][number].tolist(), plan["inks"][number].tolist()
        order, seen, n_bones = plan["order"][number], plan["seen"][number], plan["bones"]
        core = draw.draw
        for k in order[seen[order]].tolist():
            if k < n_bones:
                # No round caps: every bone ends in a joint's larger ball, drawn nearer.
                for line, ink, width in zip(lines[k], inks[k], widths[k]):
                    core.draw_lines(line, ink, width)
            else:
                for disc, ink in zip(discs[k - n_bones], inks[k]):
                    core.draw_ellipse(disc, ink, 1)

"""Body meshes: a smooth SMPL-like body around the skeleton, lit, on the shared floor.

The body (see :mod:`rendering.body`) is drawn offscreen by pyrender through EGL and laid
over the same backdrop and soft floor shadow as the stick figures, in the set's framing.
A motion that carries its own body surface (an SMPL mesh from an import) is drawn with
that surface instead (:mod:`rendering.surface`), placed, lit and shadowed the same way.
Every clip gets the same neutral body colour; left limbs are a shade warmer and right
ones a shade cooler, just enough to tell the sides apart.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from PIL import Image, ImageChops, ImageDraw, ImageFilter

from motion.motion import Motion
from motion.skeletons import get_skeleton
from rendering import palette
from rendering.backdrop import Backdrop
from rendering.body import Body
from rendering.surface import SurfaceBody
from rendering.framing import Framing
from rendering.stage import Stage
from rendering.styles.base import Style, register_style
from rendering.styles.stick import NEAR, SHADOW_BLUR_LEAST

BODY = np.array([168.0, 172.0, 182.0])  # a cool light grey, sRGB
TINT = 0.16  # how far left and right limbs lean towards the palette's warm and cool
AMBIENT = 0.3
KEY, FILL, RIM = 2.2, 1.4, 0.6  # directional light intensities
SHADOW_SHRINK = 2  # the shadow is drawn this much smaller, then blurred and stretched


def _linear(srgb: np.ndarray) -> np.ndarray:
    """Return linear-light values of sRGB colours in [0, 255] (pyrender shades linearly)."""
    c = np.asarray(srgb, dtype=float) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def body_colours(sides: np.ndarray) -> np.ndarray:
    """Return each vertex's linear RGBA colour from its side (``left``/``right``/``centre``)."""
    tinted = {
        "left": BODY + (palette.LEFT - BODY) * TINT,
        "right": BODY + (palette.RIGHT - BODY) * TINT,
        "centre": BODY,
    }
    colours = np.array([_linear(tinted[side]) for side in sides])
    return np.concatenate([colours, np.ones((len(sides), 1))], axis=1)


def composite(backdrop: np.ndarray, rgba: np.ndarray, box) -> np.ndarray:
    """Lay the premultiplied window ``rgba`` over ``backdrop`` at ``box`` (left, top, ...)."""
    left, top, right, bottom = box
    part = np.s_[top:bottom, left:right]
    over = rgba.astype(np.uint16)
    under = backdrop[part].astype(np.uint16)
    mixed = over[..., :3] + (under * (255 - over[..., 3:4]) + 127) // 255
    backdrop[part] = np.minimum(mixed, 255).astype(np.uint8)
    return backdrop


@register_style("mesh")
class MeshStyle(Style):
    """Smooth lit bodies on the checker floor; needs EGL (pyrender) but no GPU."""

    dims = 3
    pad = 0.12  # an SMPL head reaches this far above its head joint, per figure height
    player_figure = "body"

    def __init__(self, framing: Framing, width: int, height: int):
        super().__init__(framing, width, height)
        self._backdrop = Backdrop(framing, width, height)
        self._backdrops = {(framing, (0, 0)): self._backdrop}
        self._stills = {}
        self._stage: Stage | None = None
        self._shown = None

    def reach(self, skeleton: str):
        """Return how far the body reaches beyond each joint, per figure height: the head
        ``pad``, the feet (toe tips ahead of the ankles) and hands as far, limbs and
        trunk 0.05 (half-thicknesses are at most 0.04: :mod:`rendering.body`); a
        skeleton without a body layout: ``pad`` everywhere."""
        from rendering.body import LAYOUTS

        found = get_skeleton(skeleton)
        layout = LAYOUTS.get(found.family)
        if layout is None:
            return self.pad
        index = {name: j for j, name in enumerate(found.joint_names)}
        reach = np.full(found.n_joints, 0.05)
        ends = [(layout.head, self.pad)]
        ends += [(leg[-1], self.pad) for leg in layout.legs]
        ends += [(toe, self.pad) for toe in layout.toes or ()]
        ends += [(arm[-1], self.pad) for arm in layout.arms]
        ends += [(hand, self.pad) for hand in layout.hands or ()]
        for name, value in ends:
            if name in index:
                reach[index[name]] = value
        return reach

    def _body(self, motion: Motion, placed: np.ndarray):
        """Return the body drawn on the placed joints (its own surface, if it has one)."""
        skeleton = get_skeleton(motion.skeleton)
        if skeleton.dims != 3:
            raise ValueError(
                f"the mesh style draws 3D skeletons; {skeleton.name!r} is {skeleton.dims}D"
            )
        if motion.has_body:
            return SurfaceBody(skeleton, motion, placed)
        return Body(skeleton, placed)

    def filmed(self, motion: Motion) -> np.ndarray:
        """Return the placed joints lifted as the body is, its soles on the floor."""
        placed = self.framing.place(motion)
        return placed + [0.0, 0.0, self._lift(self._body(motion, placed), placed)]

    def frames(self, motion: Motion) -> Iterator[np.ndarray]:
        placed = self.framing.place(motion)
        body = self._body(motion, placed)
        lift = self._lift(body, placed)
        placed = placed + [0.0, 0.0, lift]
        body.lift(lift)
        shot = self.framing.shot(motion, self.width, self.height, self.reach(motion.skeleton),
                                 placed)
        framing, targets = shot.framing, shot.targets
        canvas = shot.canvas(self.width, self.height)
        for number, (pose, target) in enumerate(zip(placed, targets)):
            stage = self._stage_for(body)  # per frame: clips of a grid take turns
            vertices, normals, centres, radii = body.pose_at(number, pose)
            camera = shot.camera(self.width, self.height, target)
            frame = self._scenery(shot, target)
            self._cast_shadow(frame, camera, centres, radii, framing)
            box = stage.window(camera.project(vertices)[0], *canvas)
            if box is not None:
                composite(frame, stage.draw(vertices, normals, camera, box), box)
            yield shot.cut(frame, number, self.width, self.height)

    def close(self) -> None:
        if self._stage is not None:
            self._stage.close()
            self._stage = None

    @staticmethod
    def _lift(body, placed: np.ndarray) -> float:
        """Return how far to raise a clip so that its soles, not its lowest joint, touch down.

        Measured where the lowest joint is lowest and applied to every frame, so a
        set's shared floor still shows a clip that floats or sinks.
        """
        lowest = int(np.argmin(placed[..., 2].min(axis=1)))
        vertices = body.pose_at(lowest, placed[lowest])[0]
        return float(placed[lowest, :, 2].min() - vertices[:, 2].min())

    def _stage_for(self, body: Body) -> Stage:
        if self._stage is None:
            framing = self.framing
            fall = framing.shadows(np.array([0.0, 0.0, 1.0]))  # where a unit height's shadow falls
            key = np.array([-fall[0], -fall[1], 1.0])
            right, _, forward = framing.camera(2, 2).rotation
            # A fill from the camera's upper left models the front; a rim light from
            # behind on the right separates the far side from the floor.
            fill = -forward * [1, 1, 0] - right * 0.7 + [0, 0, 0.6]
            rim = forward * [1, 1, 0] + right * 0.6 + [0, 0, 0.4]
            self._stage = Stage(
                near=0.02 * framing.distance, far=10.0 * framing.distance + 10.0 * framing.height,
                lights=((key, KEY), (fill, FILL), (rim, RIM)), ambient=AMBIENT,
            )
        key = body.key
        if self._shown != key:
            self._stage.show(body.faces, body_colours(body.sides))
            self._shown = key
        return self._stage

    def _scenery(self, shot, target) -> np.ndarray:
        """Return a fresh copy of a shot's backdrop with the look-at at ``target``."""
        key = (shot.framing, shot.margin)
        if key not in self._backdrops:
            if len(self._backdrops) > 4:  # a clip needing a larger canvas is rare
                for old in list(self._backdrops)[1:]:
                    del self._backdrops[old]
                    self._stills.pop(old, None)
            self._backdrops[key] = Backdrop(shot.framing, self.width, self.height, shot.margin)
        backdrop = self._backdrops[key]
        if self.framing.follow:
            return backdrop.image(target)
        if key not in self._stills:
            self._stills[key] = backdrop.image()
        return self._stills[key].copy()

    def _cast_shadow(self, frame: np.ndarray, camera, centres, radii,
                     framing: Framing | None = None) -> None:
        """Darken the floor under the body: a soft shadow plus a darker one at contacts.

        Every ring of the body is a disc in the shadow, drawn small, blurred and stretched;
        parts near the floor add a tighter, darker layer, as the stick figures' do.
        """
        framing = framing or self.framing
        height = framing.height
        seen = camera.project(framing.shadows(centres))[1] > NEAR * framing.distance
        if not seen.any():
            return
        centres, radii = centres[seen], radii[seen]  # none of what lies at or behind the eye
        pixels, depth = camera.project(framing.shadows(centres))
        pixels = pixels / SHADOW_SHRINK
        reach = camera.pixel_size(depth) * radii / SHADOW_SHRINK
        unit = height * float(camera.pixel_size(framing.distance)) / SHADOW_SHRINK
        bottom = centres[:, 2] - radii
        closeness = 1.0 - np.clip(bottom / (0.15 * height), 0.0, 1.0)
        layers = ((np.full(len(centres), 90.0), 1.0, 0.02), (closeness**2 * 140, 0.9, 0.008))

        border = reach + 4 * max(SHADOW_BLUR_LEAST, 0.02 * unit) + 2
        size = np.array([camera.width, camera.height]) // SHADOW_SHRINK
        low = np.maximum(np.floor((pixels - border[:, None]).min(axis=0)), 0).astype(int)
        high = np.minimum(np.ceil((pixels + border[:, None]).max(axis=0)), size).astype(int)
        if (high <= low).any():
            return
        pixels = pixels - low
        masks = []
        for strength, spread, blur in layers:
            mask = Image.new("L", tuple(high - low), 0)
            draw = ImageDraw.Draw(mask)
            for ring in np.argsort(strength, kind="stable"):  # darkest last: it stays on top
                (x, y), radius, level = pixels[ring], spread * reach[ring], int(strength[ring])
                if level > 0:
                    draw.ellipse((x - radius, y - radius, x + radius, y + radius), fill=int(level))
            sigma = max(SHADOW_BLUR_LEAST, blur * unit)
            masks.append(mask.filter(ImageFilter.GaussianBlur(sigma)))
        mask = ImageChops.add(*masks)
        stretched = (mask.width * SHADOW_SHRINK, mask.height * SHADOW_SHRINK)
        mask = mask.resize(stretched, Image.BILINEAR)
        image = Image.fromarray(frame)
        image.paste(palette.SHADOW, tuple(int(v) * SHADOW_SHRINK for v in low), mask)
        frame[...] = np.asarray(image)

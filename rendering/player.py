"""Motion payloads for the in-browser player: quantised joints in a set's framing.

A payload is what ``motion-player.js`` draws instead of playing a video: the placed
joints of every frame as int16 (one step for the whole set, from its framing), how the
clip's rendered video films each frame (:meth:`rendering.framing.Framing.shot`: the
look-at, and the frame's window over the larger canvas), the camera rule and what the
figure needs (parents, sides and radii). Its byte size depends only on the clip's length
and skeleton, and nothing in it names a source, an action or a file: like a video, it is
served under an opaque token.

Layout (little-endian)::

    magic "MPLY", version u16, frames u16, joints u16, flags u16 (bit 0: orthographic)
    f32: fps, step (metres per unit), azimuth, elevation, fov, distance (the set's),
         window step (frame heights per unit), figure height, shadow slant,
         stick bone radius (metres)
    i8[joints]: parent of each joint (-1 for the root)
    i8[joints]: side of each joint (1 left, -1 right, 0 centre)
    u16[joints]: stick joint radius, u16[joints]: body radius of the bone ending there
    (padding to 4 bytes)
    i16[frames][joints][3]: placed joints (z up, on the floor)
    i16[frames][3]: the camera's look-at (x, y, z) per frame
    i16[frames][2]: the frame's window per frame, moved right and down from where the
                    camera's axis puts it (in window steps: shares of the frame's height)
    i16[frames]: the eye's distance per frame, in ZOOM_STEPS of the set's distance (more
                 only for a figure larger than the frame on some frame: zoomed out)

Radii are in the same units as positions. Everything a clip's content decides is in
the int16 arrays (dithered per delivery); the header is the set's. Version 1 (a 2-D look-at and one look-at
height, no window) framed clips by the rule's follow camera alone; it is refused.
"""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import numpy as np

from motion.motion import Motion
from motion.skeletons import get_skeleton
from rendering.framing import PAD, SHADOW_SLANT, Framing
from rendering.styles.stick import BONE_RADIUS, Figure

# The figures motion-player.js draws a payload as (a style's ``player_figure``).
FIGURES = ("stick", "body")
MAGIC = b"MPLY"
VERSION = 2
STEPS_PER_HEIGHT = 4096  # int16 then reaches 8 figure heights either way of the origin
WINDOW_STEPS = 8192  # per frame height: a window moves up to 4 frame heights either way
ZOOM_STEPS = 2048  # per the set's distance: a clip is filmed up to 16 times farther away
SIZE = 480  # the frame a shot is worked out for, by default (render.size's default)
HEADER = struct.Struct("<4sHHHH10f")
SUFFIX = ".motion"
# Half-thicknesses of the body's bones, per figure height: the mesh style's proportions
# (rendering.body gives limbs about these at mid-length, the trunk its width).
BODY_RADII = {"trunk": 0.085, "pelvis": 0.06, "shoulder": 0.045, "neck": 0.035,
              "head": 0.065, "upper_leg": 0.045, "lower_leg": 0.034, "foot": 0.026,
              "upper_arm": 0.03, "lower_arm": 0.025, "hand": 0.02}


class PayloadError(ValueError):
    """Bytes that are not a motion payload of this version."""


def _checked(data: bytes) -> tuple:
    """Return a payload's header fields, or raise :class:`PayloadError` saying why not."""
    if len(data) < HEADER.size or data[:4] != MAGIC:
        raise PayloadError("not a motion payload (no MPLY header)")
    fields = HEADER.unpack_from(data)
    version, frames, joints = fields[1:4]
    if version != VERSION:
        raise PayloadError(f"motion payload version {version}; this reads version {VERSION} "
                           "(rebuild the stimuli: manage.py build_stimuli)")
    if len(data) != size(frames, joints):
        raise PayloadError(f"payload of {len(data)} bytes; {frames} frames of {joints} joints "
                           f"need {size(frames, joints)}")
    return fields


def _body_part(name: str) -> str:
    """Return the body part a bone ending at a joint named ``name`` belongs to."""
    name = name.lower()
    for keys, part in ((("hip",), "pelvis"), (("shoulder", "collar"), "shoulder"),
                       (("knee",), "upper_leg"), (("ankle", "foot"), "lower_leg"),
                       (("toe",), "foot"), (("elbow",), "upper_arm"),
                       (("wrist",), "lower_arm"), (("hand",), "hand"), (("head",), "head"),
                       (("neck", "nose"), "neck")):
        if any(key in name for key in keys):
            return part
    return "trunk"


def figure_radii(skeleton_name: str, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Return each joint's stick radius and the body radius of the bone ending at it."""
    skeleton = get_skeleton(skeleton_name)
    stick = Figure(skeleton, height).joint_radii
    body = np.array([BODY_RADII[_body_part(n)] * height for n in skeleton.joint_names])
    return stick, body


def payload(motion: Motion, framing: Framing, size=SIZE, pad=PAD,
            placed: np.ndarray | None = None) -> bytes:
    """Return the motion's payload in a set's framing (see the module's layout), filmed
    as its video of ``size`` pixels (one number for a square, or width and height) is:
    ``pad`` is the style's reach (:meth:`rendering.styles.base.Style.reach`), ``placed``
    the joints as the style films them (:meth:`rendering.styles.base.Style.filmed`;
    default: as the framing places them)."""
    skeleton = get_skeleton(motion.skeleton)
    width, height = (size, size) if np.isscalar(size) else size
    placed = framing.place(motion) if placed is None else placed
    shot = framing.shot(motion, int(width), int(height), pad, placed)
    step = framing.height / STEPS_PER_HEIGHT
    stick, body = figure_radii(motion.skeleton, framing.height)
    header = HEADER.pack(
        MAGIC, VERSION, motion.frames, skeleton.n_joints, int(framing.orthographic),
        float(motion.fps), step, framing.azimuth, framing.elevation, framing.fov,
        framing.distance, 1.0 / WINDOW_STEPS, framing.height, SHADOW_SLANT,
        BONE_RADIUS * framing.height,
    )
    sides = [{"left": 1, "right": -1}.get(skeleton.side_of(j), 0) for j in range(skeleton.n_joints)]
    parts = [
        header,
        np.asarray(skeleton.parents, np.int8).tobytes(),
        np.asarray(sides, np.int8).tobytes(),
        _units(stick, step).astype("<u2").tobytes(),
        _units(body, step).astype("<u2").tobytes(),
    ]
    table = b"".join(parts)
    table += bytes(-len(table) % 4)
    windows = np.asarray(shot.offsets, np.float64).reshape(-1, 2) / int(height)
    zooms = np.full(len(placed), shot.framing.distance / framing.distance)
    return table + b"".join(
        np.clip(np.rint(values), -32767, 32767).astype("<i2").tobytes()
        for values in (placed / step, shot.targets / step, windows * WINDOW_STEPS,
                       zooms * ZOOM_STEPS))


def _units(values: np.ndarray, step: float) -> np.ndarray:
    return np.clip(np.rint(np.asarray(values) / step), 1, 65535)


def size(frames: int, joints: int) -> int:
    """Return the byte size of every payload of this length and joint count."""
    return _positions_at(joints) + 6 * frames * joints + 12 * frames


def _positions_at(joints: int) -> int:
    """Return the byte offset of a payload's int16 positions (after its padded table)."""
    table = HEADER.size + 6 * joints
    return table + (-table % 4)


def dither(data: bytes, rng) -> bytes:
    """Return a payload with one unit added or taken on a random two thirds of its int16
    values (placed joints, the camera's look-at, the frame's window and the eye's
    distance), drawn from ``rng``.

    A unit is a 4096th of the figure's height (under half a millimetre on a person), an
    8192th of the frame's height for the window, a 2048th of the distance: all far below
    a pixel. The figure drawn is the same, the bytes are not, so every delivery of a clip
    can have bytes of its own (:mod:`rendering.delivery`).
    """
    joints = _checked(data)[3]
    at = _positions_at(joints)
    values = np.frombuffer(data, "<i2", offset=at).astype(np.int32)
    values += rng.integers(-1, 2, size=values.size)
    return data[:at] + np.clip(values, -32767, 32767).astype("<i2").tobytes()


def read(data: bytes) -> dict:
    """Return a payload's fields, positions in metres and windows in frame heights (the
    inverse of :func:`payload`)."""
    (_, _, frames, joints, flags, fps, step, azimuth, elevation, fov, distance,
     window_step, height, slant, bone) = _checked(data)
    at = HEADER.size
    parents = np.frombuffer(data, np.int8, joints, at)
    sides = np.frombuffer(data, np.int8, joints, at + joints)
    stick = np.frombuffer(data, "<u2", joints, at + 2 * joints) * step
    body = np.frombuffer(data, "<u2", joints, at + 4 * joints) * step
    at = _positions_at(joints)
    positions = np.frombuffer(data, "<i2", frames * joints * 3, at).reshape(frames, joints, 3)
    at += 6 * frames * joints
    looks = np.frombuffer(data, "<i2", frames * 3, at).reshape(frames, 3)
    windows = np.frombuffer(data, "<i2", frames * 2, at + 6 * frames).reshape(frames, 2)
    zooms = np.frombuffer(data, "<i2", frames, at + 10 * frames) / ZOOM_STEPS
    return {
        "frames": frames, "joints": joints, "orthographic": bool(flags & 1), "fps": fps,
        "step": step, "azimuth": azimuth, "elevation": elevation, "fov": fov,
        "distance": distance, "window_step": window_step, "height": height,
        "shadow_slant": slant, "stick_bone_radius": bone,
        "parents": parents, "sides": sides, "stick_radii": stick, "body_radii": body,
        "positions": positions * step, "targets": looks * step,
        "windows": windows * window_step, "distances": zooms * distance,
    }


def write_payloads(motions: list[Motion], out_dir: str | Path, framing: Framing,
                   size=SIZE, style: str = "stick") -> list[tuple[Path, str]]:
    """Write each motion's payload as ``out_dir/<hash>.motion``; return (path, hash) each.

    Pass the study's framing, video size and style (those its videos use), so the player
    frames each clip as its video does. Names are the first 16 hex digits of the
    payload's sha256.
    """
    from rendering.styles import get_style

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    width, height = (size, size) if np.isscalar(size) else size
    written = []
    with get_style(style)(framing, int(width), int(height)) as drawer:
        for motion in motions:
            data = payload(motion, framing, (width, height), drawer.reach(motion.skeleton),
                           drawer.filmed(motion))
            digest = hashlib.sha256(data).hexdigest()[:16]
            path = out_dir / f"{digest}{SUFFIX}"
            path.write_bytes(data)
            written.append((path, digest))
    return written

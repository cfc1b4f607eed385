"""Motion payloads for the in-browser player: quantised joints in a set's framing.

A payload is what ``motion-player.js`` draws instead of playing a video: the placed
joints of every frame as int16 (one step for the whole set, from its framing), each
frame's camera target, the camera rule and what the figure needs (parents, sides and
radii). Its byte size depends only on the clip's length and skeleton, and nothing in it
names a source, an action or a file: like a video, it is served under an opaque token.

Layout (little-endian)::

    magic "MPLY", version u16, frames u16, joints u16, flags u16 (bit 0: orthographic)
    f32: fps, step (metres per unit), azimuth, elevation, fov, distance, target z,
         figure height, shadow slant, stick bone radius (metres)
    i8[joints]: parent of each joint (-1 for the root)
    i8[joints]: side of each joint (1 left, -1 right, 0 centre)
    u16[joints]: stick joint radius, u16[joints]: body radius of the bone ending there
    (padding to 4 bytes)
    i16[frames][joints][3]: placed joints (z up, on the floor)
    i16[frames][2]: the camera's look-at (x, y) per frame

Radii are in the same units as positions.
"""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import numpy as np

from motion.motion import Motion
from motion.skeletons import get_skeleton
from rendering.framing import SHADOW_SLANT, Framing
from rendering.styles.stick import BONE_RADIUS, Figure

# The figures motion-player.js draws a payload as (a style's ``player_figure``).
FIGURES = ("stick", "body")
MAGIC = b"MPLY"
VERSION = 1
STEPS_PER_HEIGHT = 4096  # int16 then reaches 8 figure heights either way of the origin
HEADER = struct.Struct("<4sHHHH10f")
SUFFIX = ".motion"
# Half-thicknesses of the body's bones, per figure height: the mesh style's proportions
# (rendering.body gives limbs about these at mid-length, the trunk its width).
BODY_RADII = {"trunk": 0.085, "pelvis": 0.06, "shoulder": 0.045, "neck": 0.035,
              "head": 0.065, "upper_leg": 0.045, "lower_leg": 0.034, "foot": 0.026,
              "upper_arm": 0.03, "lower_arm": 0.025, "hand": 0.02}


class PayloadError(ValueError):
    """Bytes that are not a motion payload of this version."""


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


def payload(motion: Motion, framing: Framing) -> bytes:
    """Return the motion's payload in a set's framing (see the module's layout)."""
    skeleton = get_skeleton(motion.skeleton)
    placed = framing.place(motion)
    targets = framing.targets(motion, placed)[:, :2]
    step = framing.height / STEPS_PER_HEIGHT
    stick, body = figure_radii(motion.skeleton, framing.height)
    header = HEADER.pack(
        MAGIC, VERSION, motion.frames, skeleton.n_joints, int(framing.orthographic),
        float(motion.fps), step, framing.azimuth, framing.elevation, framing.fov,
        framing.distance, framing.target[2], framing.height, SHADOW_SLANT,
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
    joints = np.clip(np.rint(placed / step), -32767, 32767).astype("<i2")
    looks = np.clip(np.rint(targets / step), -32767, 32767).astype("<i2")
    return table + joints.tobytes() + looks.tobytes()


def _units(values: np.ndarray, step: float) -> np.ndarray:
    return np.clip(np.rint(np.asarray(values) / step), 1, 65535)


def size(frames: int, joints: int) -> int:
    """Return the byte size of every payload of this length and joint count."""
    return _positions_at(joints) + 6 * frames * joints + 4 * frames


def _positions_at(joints: int) -> int:
    """Return the byte offset of a payload's int16 positions (after its padded table)."""
    table = HEADER.size + 6 * joints
    return table + (-table % 4)


def dither(data: bytes, rng) -> bytes:
    """Return a payload with one unit added or taken on a random two thirds of its int16
    values (placed joints and the camera's look-at), drawn from ``rng``.

    A unit is a 4096th of the figure's height (under half a millimetre on a person), far
    below a pixel: the figure drawn is the same, the bytes are not, so every delivery of
    a clip can have bytes of its own (:mod:`rendering.delivery`).
    """
    if len(data) < HEADER.size or data[:4] != MAGIC:
        raise PayloadError("not a motion payload (no MPLY header)")
    frames, joints = HEADER.unpack_from(data)[2:4]
    if len(data) != size(frames, joints):
        raise PayloadError(f"payload of {len(data)} bytes; {frames} frames of {joints} joints "
                           f"need {size(frames, joints)}")
    at = _positions_at(joints)
    values = np.frombuffer(data, "<i2", offset=at).astype(np.int32)
    values += rng.integers(-1, 2, size=values.size)
    return data[:at] + np.clip(values, -32767, 32767).astype("<i2").tobytes()


def read(data: bytes) -> dict:
    """Return a payload's fields, positions in metres (the inverse of :func:`payload`)."""
    if len(data) < HEADER.size or data[:4] != MAGIC:
        raise PayloadError("not a motion payload (no MPLY header)")
    (_, version, frames, joints, flags, fps, step, azimuth, elevation, fov, distance,
     target_z, height, slant, bone) = HEADER.unpack_from(data)
    if version != VERSION:
        raise PayloadError(f"payload version {version}; this reads version {VERSION}")
    if len(data) != size(frames, joints):
        raise PayloadError(f"payload of {len(data)} bytes; {frames} frames of {joints} joints "
                           f"need {size(frames, joints)}")
    at = HEADER.size
    parents = np.frombuffer(data, np.int8, joints, at)
    sides = np.frombuffer(data, np.int8, joints, at + joints)
    stick = np.frombuffer(data, "<u2", joints, at + 2 * joints) * step
    body = np.frombuffer(data, "<u2", joints, at + 4 * joints) * step
    at = _positions_at(joints)
    positions = np.frombuffer(data, "<i2", frames * joints * 3, at).reshape(frames, joints, 3)
    looks = np.frombuffer(data, "<i2", frames * 2, at + 6 * frames * joints).reshape(frames, 2)
    return {
        "frames": frames, "joints": joints, "orthographic": bool(flags & 1), "fps": fps,
        "step": step, "azimuth": azimuth, "elevation": elevation, "fov": fov,
        "distance": distance, "target_z": target_z, "height": height, "shadow_slant": slant,
        "stick_bone_radius": bone,
        "parents": parents, "sides": sides, "stick_radii": stick, "body_radii": body,
        "positions": positions * step, "targets": looks * step,
    }


def write_payloads(motions: list[Motion], out_dir: str | Path,
                   framing: Framing) -> list[tuple[Path, str]]:
    """Write each motion's payload as ``out_dir/<hash>.motion``; return (path, hash) each.

    Pass the study's framing (the one its videos use), so the player shows what the
    videos show. Names are the first 16 hex digits of the payload's sha256.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for motion in motions:
        data = payload(motion, framing)
        digest = hashlib.sha256(data).hexdigest()[:16]
        path = out_dir / f"{digest}{SUFFIX}"
        path.write_bytes(data)
        written.append((path, digest))
    return written


"""BVH motion capture files (CMU, Mixamo, Bandai-Namco, LAFAN1, MoMask, smpl2bvh, Blender,
MotionBuilder, ...): parse, forward kinematics, map to a skeleton, write.

:func:`load` (the ``bvh`` format) reads a file, or a folder of them, one motion per file:
as the file's own skeleton (its hierarchy becomes a custom skeleton, drawn and used in a
study as it is; sides from ``Left``/``Right``, ``l_``/``r_``, ``_L``/``_R``, ``.L``/``.R``;
a static root that never turns, such as Bandai-Namco's ``joint_Root``, is a locator and
left out), or mapped onto a project skeleton (``skeleton``: ``smpl22``, ``smpl24``,
``humanact12``, ``h36m17``) through the built-in maps of SMPL-, HumanML3D- (MoMask's
``joints2bvh``), LAFAN1-, Bandai-Namco-, CMU- and Mixamo-style joint names (a prefix every
joint shares, ``mixamorig:`` or MotionBuilder's ``Character1_``, is ignored).
:func:`read` parses one file; :func:`save` writes a motion's joints as BVH.

A BVH file has two parts:

- ``HIERARCHY``: one ``ROOT`` and nested ``JOINT`` blocks, each with ``OFFSET x y z`` from
  its parent and ``CHANNELS n ...`` (``Xposition``, ``Yposition``, ``Zposition``,
  ``Xrotation``, ``Yrotation``, ``Zrotation``, in any order); an ``End Site`` block has
  only an offset and marks the tip of a chain (the top of the head, a toe tip).
- ``MOTION``: ``Frames: T``, ``Frame Time: dt`` (seconds), then one line per frame with
  every channel's value in hierarchy order; rotations in degrees.

Forward kinematics: a joint's transform in its parent's frame is the translation by its
offset, whose components its position channels replace (Holden's reader, the one LAFAN1
uses: Mixamo's root OFFSET holds the rest hip height and its channels absolute hip
positions; Bandai-Namco and Blender repeat every joint's offset in six channels), then
its rotation channels in the order listed (``Zrotation Yrotation Xrotation`` gives
``R = Rz @ Ry @ Rx``); its world position is the translation of the product of the
transforms from the root down.

A figure whose largest extent is outside 1.0-2.3 m, or whose lowest joint is more than
0.25 m off the floor (up = 0), gets a warning (the result's ``notes``) saying what was
assumed: the unit and how it was chosen, the up axis, the floor.

Units: BVH files carry none. ``scale`` is metres per file unit: a number, a unit name of
:data:`UNITS`, or ``"auto"`` (the default), which picks the unit that makes the rest pose
(all channels zero) closest to :data:`TYPICAL_HEIGHT` tall, measuring its largest extent
along any axis (the height, or a T-pose's arm span, which is about the same). CMU's BVH
conversions keep the ASF length unit, 1/0.45 inch (``"cmu"``, 5.644 cm): a CMU subject
is about 25 units tall. The guess cannot tell a child in inches from an adult in CMU
units; pass ``scale`` when the body's size matters.

Axes: BVH is y up by convention; pass ``up`` for files that are not. :func:`to_skeleton`
rotates the joints onto the project skeleton's up axis (h36m17 is z up, humanact12 y up).

Lines starting with ``#`` (comments some converters write, e.g. ``#name: ...``) are
skipped. Each motion's action is ``action`` when given, else its prompt (``texts``: a
file of one prompt per line or a CSV, see :func:`motion.formats.base.read_prompts`),
else the file's name.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion.formats.bvh_names import END_SUFFIX, JOINT_MAPS
from motion.formats.base import (
    FormatError,
    MotionList,
    files_in,
    format_module,
    load_each,
    prompt_file_beside,
    prompts_for,
    read_prompts,
)
from motion.motion import Motion
from motion.ops import axis_rotation
from motion.skeletons import custom_skeleton, get_skeleton

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}
TYPICAL_HEIGHT = 1.7  # metres
CHANNELS = {f"{axis}{kind}": (kind, i) for i, axis in enumerate("XYZ")
            for kind in ("position", "rotation")}


class BvhError(FormatError):
    """A BVH file is unreadable, malformed, or cannot be mapped onto a skeleton."""


@dataclass(frozen=True, eq=False)
class BvhMotion:
    """World joint positions of one BVH file.

    ``joint_names`` and ``parents`` (``-1`` for the root) list the ROOT and JOINTs and
    the End Sites (named ``<joint>_End``, indices in ``end_sites``) in file order;
    ``offsets`` ``(J, 3)`` and ``positions`` ``(T, J, 3)`` are in metres, in the file's
    axes (``up`` names the vertical one); ``scale`` is the metres per file unit used.
    ``locators`` are roots that only place the figure (a static ``joint_Root`` on the
    floor, without rotation): not bones. ``warnings`` say what was assumed of a figure
    whose size or height above the floor is implausible.
    """

    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    positions: np.ndarray
    fps: float
    scale: float
    up: str = "y"
    end_sites: tuple[int, ...] = ()
    path: str = ""
    locators: tuple[int, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)


@dataclass
class _Joint:
    name: str
    parent: int
    line: int
    offset: np.ndarray | None = None
    channels: tuple[tuple[str, int], ...] = ()
    end_site: bool = False


def load(path: str | Path, skeleton: str | None = None, action: str | None = None,
         mapping: dict[str, str] | None = None, scale: float | str = "auto", up: str = "y",
         texts: str | Path | None = None, source: str = "real") -> list[Motion]:
    """Read a BVH file, or every ``.bvh`` under a folder, one motion per file.

    Without ``skeleton`` each file is its own skeleton; with one, its joints are mapped
    onto it (see :func:`joint_map`). Bad files of a folder are reported by name in the
    result's ``problems``. ``texts`` (or a ``prompts.txt``/``.csv`` beside the files)
    gives each file's prompt.
    """
    path = Path(path)
    files = files_in(path, ("*.bvh", "*.BVH"), "BVH files")
    prompts = [None] * len(files)
    prompt_file = Path(texts) if texts else prompt_file_beside(files, path)
    if prompt_file is not None:
        prompts = prompts_for(files, read_prompts(prompt_file), prompt_file)

    def one(file: Path, text: str | None) -> list[Motion]:
        parsed = read(file, scale, up)
        label = action or text or file.stem
        notes = [f"warning: {warning}" for warning in parsed.warnings]
        if not skeleton:
            return MotionList([own_skeleton(parsed, label, source, text)], notes=notes)
        try:
            return MotionList([to_skeleton(parsed, skeleton, mapping, label, source, text)],
                              notes=notes)
        except KeyError as exc:  # an unknown skeleton name
            raise BvhError(exc.args[0]) from None

    by_file = dict(zip(files, prompts))
    return load_each(files, lambda file: one(file, by_file[file]), "BVH file")


def read(path: str | Path, scale: float | str = "auto", up: str = "y") -> BvhMotion:
    """Read a BVH file and return its joints' world positions in metres (see module doc)."""
    path = Path(path)
    if up not in ("x", "y", "z"):
        raise BvhError(f"up must be 'x', 'y' or 'z'; got {up!r}")
    if not path.is_file():
        raise BvhError(f"BVH file {path} does not exist")
    text = path.read_text(encoding="utf-8", errors="replace")
    # Blank comment lines, keeping the line numbers of errors true.
    text = re.sub(r"^[ \t]*(#|//).*$", "", text, flags=re.MULTILINE)
    split = re.search(r"^\s*MOTION\s*$", text, flags=re.MULTILINE | re.IGNORECASE)
    if split is None:
        raise BvhError(f"{path}: no MOTION section; a BVH file is HIERARCHY ... then MOTION ...")
    joints = _parse_hierarchy(text[:split.start()], path)
    first_line = text.count("\n", 0, split.end()) + 1
    values, frame_time = _parse_motion(text[split.end():], joints, path, first_line)
    parents = [j.parent for j in joints]
    offsets = np.array([j.offset for j in joints], dtype=np.float64)
    metres = _scale(scale, rest_pose(offsets, parents), path)
    positions = _forward_kinematics(joints, values) * metres
    locators = _locators(joints, values, positions)
    warnings = _implausible(positions, locators, up, metres, scale, path)
    return BvhMotion(
        joint_names=tuple(j.name for j in joints),
        parents=tuple(parents),
        offsets=(offsets * metres).astype(np.float32),
        positions=positions.astype(np.float32),
        fps=_fps(frame_time),
        scale=metres,
        up=up,
        end_sites=tuple(i for i, j in enumerate(joints) if j.end_site),
        path=str(path),
        locators=locators,
        warnings=tuple(warnings),
    )


def _locators(joints: list[_Joint], values: np.ndarray, positions: np.ndarray) -> tuple[int, ...]:
    """Return the root if it only places the figure: it never turns, never moves, and
    carries one joint (Bandai-Namco's ``joint_Root`` on the floor under ``Hips``)."""
    children = [i for i, j in enumerate(joints) if j.parent == 0 and not j.end_site]
    if len(children) != 1 or joints[children[0]].end_site:
        return ()
    root = joints[0]
    columns = [c for c, (kind, _) in enumerate(root.channels) if kind == "rotation"]
    turns = bool(columns) and bool(np.ptp(values[:, columns], axis=0).max() > 1e-6
                                   or np.abs(values[:, columns]).max() > 1e-6)
    moves = float(np.ptp(positions[:, 0], axis=0).max()) > 1e-6
    return () if turns or moves else (0,)


PLAUSIBLE_HEIGHT = (1.0, 2.3)  # metres
FLOOR_TOLERANCE = 0.25  # metres between the lowest joint and the floor


def _implausible(positions: np.ndarray, locators, up: str, metres: float, scale,
                 path: Path) -> list[str]:
    """Return warnings for a figure of implausible size or height above the floor, saying
    what was assumed (the unit, the up axis, the floor at zero)."""
    body = positions[:, [j for j in range(positions.shape[1]) if j not in locators]]
    axis = "xyz".index(up)
    unit = next((name for name, value in UNITS.items() if value == metres), f"{metres:g} m")
    how = "guessed from the rest pose" if scale == "auto" else "as given"
    warnings = []
    size = float(np.median(np.ptp(body, axis=1).max(axis=1)))
    low, high = PLAUSIBLE_HEIGHT
    if not low <= size <= high:
        warnings.append(
            f"{path.name}: the figure is {size:.2f} m tall (its largest extent), outside a "
            f"plausible {low}-{high} m; assumed the unit {unit} ({how}); if that is wrong "
            f"pass --scale (one of {', '.join(UNITS)}, or metres per unit)")
    lowest = float(np.median(body[:, :, axis].min(axis=1)))
    if abs(lowest) > FLOOR_TOLERANCE:
        where = "above" if lowest > 0 else "below"
        warnings.append(
            f"{path.name}: the lowest joint is {abs(lowest):.2f} m {where} the floor (median "
            f"over frames); assumed {up} up and the floor at {up} = 0; if the file is not "
            f"{up} up pass --up, else it is drawn as it is, off the floor")
    return warnings


def _parse_hierarchy(text: str, path: Path) -> list[_Joint]:
    """Return the joints of the HIERARCHY section, parents before children."""
    tokens = [(word, number) for number, line in enumerate(text.splitlines(), 1)
              for word in line.split()]
    if not tokens or tokens[0][0].upper() != "HIERARCHY":
        raise BvhError(f"{path}: does not start with HIERARCHY; is it a BVH file?")
    joints: list[_Joint] = []
    open_blocks: list[int] = []
    opening: int | None = None  # a joint named but whose '{' is still to come
    pos, closed = 1, False

    def fail(message: str, line: int) -> BvhError:
        return BvhError(f"{path}, line {line}: {message}")

    while pos < len(tokens):
        word, line = tokens[pos]
        key = word.upper()
        if closed:
            raise fail(f"{word!r} after the ROOT's block; only one ROOT is supported", line)
        if opening is not None and word != "{":
            raise fail(f"expected '{{' after {joints[opening].name!r}; got {word!r}", line)
        if key in ("ROOT", "JOINT"):
            if pos + 1 >= len(tokens):
                raise fail(f"{key} without a name", line)
            if key == "ROOT" and open_blocks:
                raise fail("ROOT inside another joint; only one ROOT is supported", line)
            if key == "JOINT" and (not open_blocks or joints[open_blocks[-1]].end_site):
                raise fail("JOINT outside a ROOT or JOINT block", line)
            parent = open_blocks[-1] if open_blocks else -1
            joints.append(_Joint(tokens[pos + 1][0], parent, line))
            opening, pos = len(joints) - 1, pos + 2
        elif key == "END":
            if (pos + 1 >= len(tokens) or tokens[pos + 1][0].upper() != "SITE" or not open_blocks
                    or joints[open_blocks[-1]].end_site):
                raise fail("'End' must be 'End Site' inside a ROOT or JOINT block", line)
            owner = joints[open_blocks[-1]]
            joints.append(_Joint(owner.name + END_SUFFIX, open_blocks[-1], line, end_site=True))
            opening, pos = len(joints) - 1, pos + 2
        elif word == "{":
            open_blocks.append(opening)
            opening, pos = None, pos + 1
        elif word == "}":
            if not open_blocks:
                raise fail("'}' without an open block", line)
            joint = joints[open_blocks.pop()]
            if joint.offset is None:
                raise fail(f"{joint.name!r} (line {joint.line}) has no OFFSET", line)
            closed, pos = not open_blocks, pos + 1
        elif key == "OFFSET":
            if not open_blocks:
                raise fail("OFFSET outside a joint", line)
            joints[open_blocks[-1]].offset = _numbers(tokens[pos + 1:pos + 4], 3, "OFFSET", path)
            pos += 4
        elif key == "CHANNELS":
            pos = _parse_channels(tokens, pos, joints[open_blocks[-1]] if open_blocks else None,
                                  path)
        else:
            raise fail(f"unexpected {word!r}; expected ROOT, JOINT, End Site, OFFSET, "
                       "CHANNELS, '{' or '}'", line)
    if not joints:
        raise BvhError(f"{path}: HIERARCHY has no ROOT")
    if open_blocks or opening is not None:
        raise BvhError(f"{path}: HIERARCHY ends inside {joints[-1].name!r}; a '}}' is missing")
    return joints


def _parse_channels(tokens, pos: int, joint: _Joint | None, path: Path) -> int:
    """Store a CHANNELS line on its joint; return the position after it."""
    line = tokens[pos][1]
    if joint is None or joint.end_site:
        raise BvhError(f"{path}, line {line}: CHANNELS outside a ROOT or JOINT")
    try:
        count = int(tokens[pos + 1][0])
    except (IndexError, ValueError):
        raise BvhError(f"{path}, line {line}: CHANNELS needs a count, e.g. CHANNELS 3 "
                       "Zrotation Xrotation Yrotation") from None
    names = [word for word, _ in tokens[pos + 2:pos + 2 + count]]
    lookup = {name.lower(): value for name, value in CHANNELS.items()}
    unknown = [name for name in names if name.lower() not in lookup]
    if len(names) != count or unknown:
        raise BvhError(
            f"{path}, line {line}: CHANNELS {count} of {joint.name!r} lists {names}; "
            f"channels are {', '.join(CHANNELS)}"
        )
    joint.channels = tuple(lookup[name.lower()] for name in names)
    return pos + 2 + count


def _numbers(tokens, count: int, what: str, path: Path) -> np.ndarray:
    line = tokens[0][1] if tokens else "?"
    try:
        if len(tokens) != count:
            raise ValueError
        return np.array([float(word) for word, _ in tokens])
    except ValueError:
        raise BvhError(f"{path}, line {line}: {what} needs {count} numbers") from None


def _parse_motion(text: str, joints: list[_Joint], path: Path, line: int):
    """Return the channel values ``(T, C)`` and the frame time of the MOTION section."""
    match = re.match(r"\s*Frames:\s*(\d+)\s+Frame\s+Time:\s*(\S+)", text, flags=re.IGNORECASE)
    if match is None:
        raise BvhError(f"{path}, line {line}: MOTION must be followed by 'Frames: T' and "
                       "'Frame Time: seconds'")
    frames = int(match.group(1))
    try:
        frame_time = float(match.group(2))
    except ValueError:
        frame_time = -1.0
    if frame_time <= 0 or frames < 1:
        raise BvhError(f"{path}: Frames {frames} and Frame Time {match.group(2)}; both must "
                       "be positive")
    channels = sum(len(j.channels) for j in joints)
    words = text[match.end():].split()
    try:
        values = np.array(words, dtype=np.float64)
    except ValueError:
        bad = next(w for w in words if not _is_number(w))
        raise BvhError(f"{path}: MOTION holds {bad!r}, which is not a number") from None
    if values.size != frames * channels:
        raise BvhError(
            f"{path}: MOTION holds {values.size} values; expected Frames ({frames}) x "
            f"channels in HIERARCHY ({channels}) = {frames * channels}"
        )
    return values.reshape(frames, channels), frame_time


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _fps(frame_time: float) -> float:
    """Return the frame rate; rates within 0.1% of a whole number are rounded to it
    (files store 1/120 s as 0.008333)."""
    fps = 1.0 / frame_time
    return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else round(fps, 6)


def rest_pose(offsets: np.ndarray, parents) -> np.ndarray:
    """Return the joint positions ``(J, 3)`` with every channel zero (parents come first)."""
    positions = np.zeros_like(offsets, dtype=np.float64)
    for joint, parent in enumerate(parents):
        positions[joint] = offsets[joint] + (positions[parent] if parent >= 0 else 0.0)
    return positions


def guess_scale(rest: np.ndarray) -> float:
    """Return the metres per unit of :data:`UNITS` that make a rest pose ``(J, 3)`` closest
    to :data:`TYPICAL_HEIGHT` in its largest extent."""
    size = float(np.ptp(rest, axis=0).max()) if len(rest) else 0.0
    if size <= 0:
        raise ValueError("the rest pose has no extent")
    return min(UNITS.values(), key=lambda unit: abs(np.log(size * unit / TYPICAL_HEIGHT)))


def _scale(scale: float | str, rest: np.ndarray, path: Path) -> float:
    """Return metres per file unit from a number, a unit name or ``"auto"``."""
    if isinstance(scale, str):
        if scale == "auto":
            try:
                return guess_scale(rest)
            except ValueError:
                raise BvhError(f"{path}: every OFFSET is zero, so the unit cannot be "
                               f"guessed; pass scale (one of {', '.join(UNITS)} or metres "
                               "per unit)") from None
        if scale in UNITS:
            return UNITS[scale]
        try:
            scale = float(scale)
        except ValueError:
            raise BvhError(f"scale {scale!r}: give metres per unit, 'auto' or one of "
                           f"{', '.join(UNITS)}") from None
    if not scale > 0:
        raise BvhError(f"scale must be positive metres per unit; got {scale!r}")
    return float(scale)


def _rotations(axis: int, degrees: np.ndarray) -> np.ndarray:
    """Return rotations ``(T, 3, 3)`` about axis 0, 1 or 2 by angles ``(T,)`` in degrees."""
    angle = np.radians(degrees)
    cos, sin = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]  # the plane the rotation turns, right-handed
    matrices = np.zeros((len(angle), 3, 3))
    matrices[:, axis, axis] = 1.0
    matrices[:, i, i] = cos
    matrices[:, j, j] = cos
    matrices[:, i, j] = -sin
    matrices[:, j, i] = sin
    return matrices


def _forward_kinematics(joints: list[_Joint], values: np.ndarray) -> np.ndarray:
    """Return world positions ``(T, J, 3)`` (file units) from channel values ``(T, C)``.

    A joint's position channels replace its OFFSET along their axes (as Holden's reader,
    the one LAFAN1 and much motion research use, reads them): Mixamo writes the rest hip
    height in the root's OFFSET and absolute hip positions in its channels, Bandai-Namco
    repeats every joint's offset in its six channels; adding the two would float the one
    and double the bones of the other. Rotations follow in the order listed.
    """
    frames = values.shape[0]
    world = np.empty((len(joints), frames, 4, 4))
    column = 0
    for index, joint in enumerate(joints):
        local = np.tile(np.eye(4), (frames, 1, 1))
        local[:, :3, 3] = joint.offset
        turn = np.tile(np.eye(3), (frames, 1, 1))
        for kind, axis in joint.channels:
            if kind == "position":
                local[:, axis, 3] = values[:, column]
            else:
                turn = turn @ _rotations(axis, values[:, column])
            column += 1
        local[:, :3, :3] = turn
        world[index] = local if joint.parent < 0 else world[joint.parent] @ local
    return world[:, :, :3, 3].transpose(1, 0, 2)


up_rotation = axis_rotation  # the rotation taking one axis onto another


def _plain(name: str) -> str:
    """Return a joint name without a namespace prefix, lower case: 'mixamorig:Hips' -> 'hips'."""
    return name.rsplit(":", 1)[-1].lower()


def _shared_prefix(names) -> str:
    """Return the prefix every joint name shares up to a ``_`` or ``:`` (MotionBuilder's
    ``Character1_Hips``, ``Character1_LeftUpLeg``), or ``""``."""
    names = [name for name in names if not name.endswith(END_SUFFIX)]
    common = os.path.commonprefix(names) if len(names) > 1 else ""
    cut = max(common.rfind("_"), common.rfind(":"))
    return common[:cut + 1] if cut >= 0 else ""


def joint_map(bvh: BvhMotion, skeleton_name: str,
              mapping: dict[str, str] | None = None) -> dict[str, int]:
    """Return, per joint of the skeleton, the index of the BVH joint that stands for it.

    ``mapping`` ``{skeleton joint: BVH joint}`` overrides or completes the built-in maps
    of :data:`JOINT_MAPS`; the built-in map that leaves fewest joints unmapped is used.
    """
    skeleton = get_skeleton(skeleton_name)
    mapping = dict(mapping or {})
    unknown = sorted(set(mapping) - set(skeleton.joint_names))
    if unknown:
        raise BvhError(f"mapping names {', '.join(unknown)}, which are not joints of "
                       f"{skeleton.name}; its joints are {', '.join(skeleton.joint_names)}")
    exact = {name: i for i, name in reversed(list(enumerate(bvh.joint_names)))}
    plain = {_plain(name): i for i, name in reversed(list(enumerate(bvh.joint_names)))}
    prefix = _shared_prefix(bvh.joint_names)
    if prefix:
        plain.update({_plain(name[len(prefix):]): i for i, name
                      in reversed(list(enumerate(bvh.joint_names))) if name.startswith(prefix)})

    def find(name: str) -> int | None:
        return exact.get(name, plain.get(_plain(name)))

    own_names = {name: name for name in skeleton.joint_names}  # what :func:`save` writes
    candidates = [{**built_in, **mapping} for built_in in
                  (*JOINT_MAPS.get(skeleton.name, {}).values(), own_names)]
    best = min(candidates, key=lambda names: sum(
        find(names.get(joint, "")) is None for joint in skeleton.joint_names))
    missing = [joint for joint in skeleton.joint_names if find(best.get(joint, "")) is None]
    if missing:
        wanted = ", ".join(f"{joint} (from {best[joint]!r})" if joint in best else joint
                           for joint in missing)
        example = f"{missing[0]}=<BVH joint>"
        raise BvhError(
            f"{bvh.path}: cannot map these {skeleton.name} joints: {wanted}. The file's "
            f"joints are: {', '.join(bvh.joint_names)}. Pass a mapping from {skeleton.name} "
            f"joint to BVH joint, e.g. mapping={{{missing[0]!r}: '<BVH joint>'}} "
            f"(import_motions: --joint-map '{example}')"
        )
    return {joint: find(best[joint]) for joint in skeleton.joint_names}


def own_skeleton(bvh: BvhMotion, action: str = "unlabelled", source: str = "real",
                 text: str | None = None) -> Motion:
    """Return the BVH's joints as a motion of its own (custom) skeleton, in its own axes.

    End Sites that add no length (an offset of zero) are left out; the others mark the
    tips of the chains (head top, toes, fingers) and are kept. A locator root is left out
    (its joint becomes the root): it is not a bone.
    """
    keep = [j for j in range(bvh.n_joints) if j not in bvh.locators
            and (j not in bvh.end_sites or np.linalg.norm(bvh.offsets[j]) > 1e-6)]
    index = {old: new for new, old in enumerate(keep)}
    parents = [index.get(bvh.parents[j], -1) if bvh.parents[j] >= 0 else -1 for j in keep]
    names = [bvh.joint_names[j] for j in keep]
    skeleton = custom_skeleton(names, parents, up=bvh.up, units="m", prefix="bvh",
                               description=f"the hierarchy of {Path(bvh.path).name}")
    meta = {"file": bvh.path, "scale": bvh.scale}
    return Motion(bvh.positions[:, keep], skeleton.name, bvh.fps, action, source, meta=meta,
                  text=text)


def to_skeleton(bvh: BvhMotion, skeleton_name: str, mapping: dict[str, str] | None = None,
                action: str = "unlabelled", source: str = "real",
                text: str | None = None) -> Motion:
    """Return the BVH's joints that stand for a project skeleton's, on its up axis.

    ``joints`` ``(T, J, 3)`` metres; ``meta`` keeps the file and the BVH joint of each
    skeleton joint. See :func:`joint_map` for ``mapping``.
    """
    skeleton = get_skeleton(skeleton_name)
    if skeleton.dims != 3:
        raise BvhError(f"skeleton {skeleton.name!r} is {skeleton.dims}D; a BVH file maps onto "
                       "a 3D skeleton")
    indices = joint_map(bvh, skeleton.name, mapping)
    rotation = axis_rotation(bvh.up, skeleton.up).astype(np.float32)
    per_unit = skeleton.metres_per_unit or 1.0
    joints = bvh.positions[:, [indices[name] for name in skeleton.joint_names]] @ rotation.T
    meta = {"file": bvh.path, "scale": bvh.scale,
            "bvh_joints": {name: bvh.joint_names[i] for name, i in indices.items()}}
    return Motion(joints / per_unit, skeleton.name, bvh.fps, action, source, meta=meta,
                  text=text)


def save(path: str | Path, motion: Motion, units: str = "cm") -> Path:
    """Write a motion's joints as a BVH file (y up, in ``units``) and return its path.

    Joints are positions, not rotations, so every joint gets six channels whose positions
    are its place relative to its parent in each frame (rotations zero), the layout the
    Bandai-Namco dataset and Blender's exporter use: position channels replace the OFFSET
    (which holds the first frame's), so this reader, Holden's and Blender's read the same
    joints back. Names are the skeleton's; leaves end in a zero End Site. Reading it back
    with the motion's skeleton (``load(path, skeleton=..., scale=units)``) gives the joints.
    """
    skeleton = get_skeleton(motion.skeleton)
    if skeleton.dims != 3:
        raise BvhError(f"skeleton {skeleton.name!r} is {skeleton.dims}D; BVH holds 3D joints")
    roots = [j for j, parent in enumerate(skeleton.parents) if parent < 0]
    if len(roots) != 1:
        raise BvhError(f"skeleton {skeleton.name!r} has {len(roots)} roots; BVH has one ROOT")
    if units not in UNITS:
        raise BvhError(f"units {units!r}; one of {', '.join(UNITS)}")
    per_unit = (skeleton.metres_per_unit or 1.0) / UNITS[units]
    turn = axis_rotation(skeleton.up, "y")
    joints = (np.asarray(motion.joints, np.float64) * per_unit) @ turn.T
    parents = skeleton.parents
    local = joints - np.where(np.array(parents)[None, :, None] >= 0,
                              joints[:, [max(p, 0) for p in parents]], 0.0)
    children: dict[int, list[int]] = {}
    for joint, parent in enumerate(parents):
        children.setdefault(parent, []).append(joint)
    lines = ["HIERARCHY"]
    order: list[int] = []

    def block(joint: int, depth: int) -> None:
        tab = "\t" * depth
        name = re.sub(r"\s+", "_", skeleton.joint_names[joint])
        lines.extend([f"{tab}{'ROOT' if parents[joint] < 0 else 'JOINT'} {name}", f"{tab}{{",
                      f"{tab}\tOFFSET {' '.join(f'{v:.6f}' for v in local[0, joint])}",
                      f"{tab}\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation "
                      "Xrotation"])
        order.append(joint)
        for child in children.get(joint, []):
            block(child, depth + 1)
        if joint not in children:
            lines.extend([f"{tab}\tEnd Site", f"{tab}\t{{", f"{tab}\t\tOFFSET 0 0 0", f"{tab}\t}}"])
        lines.append(f"{tab}}}")

    block(roots[0], 0)
    values = np.concatenate([local[:, order], np.zeros_like(local[:, order])], axis=2)
    lines += ["MOTION", f"Frames: {motion.frames}", f"Frame Time: {1.0 / motion.fps:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in values.reshape(motion.frames, -1)]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def detect(probe) -> str | None:
    """Recognise a ``.bvh`` file."""
    return "a .bvh file" if probe.suffix == ".bvh" else None


format_module(__name__)

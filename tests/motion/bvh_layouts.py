"""BVH files written the way other tools write them, for tests (synthetic, in their layout).

One figure (metres, y up, facing +z, +x its left; 1.65 m tall, feet on the floor) written
as Mixamo, Bandai-Namco, CMU, LAFAN1, MoMask's joints2bvh, smpl2bvh, Blender and
MotionBuilder lay it out: their joint names, units, root OFFSET, channels per joint and
rotation order. Joints a layout has no name for are merged into their child.
"""

import numpy as np

HIP_HEIGHT = 0.95
HEIGHT = 1.65
# (key, parent key, offset in metres); keys ending in _end are End Sites unless named.
FIGURE = [("hips", None, (0, HIP_HEIGHT, 0)),
          ("spine", "hips", (0, 0.1, 0)), ("spine1", "spine", (0, 0.12, 0)),
          ("spine2", "spine1", (0, 0.12, 0)), ("neck", "spine2", (0, 0.12, 0)),
          ("head", "neck", (0, 0.1, 0)), ("head_end", "head", (0, 0.14, 0))]
for _side, _sign in (("left", 1), ("right", -1)):
    FIGURE += [(f"{_side}_upleg", "hips", (_sign * 0.09, -0.05, 0)),
               (f"{_side}_leg", f"{_side}_upleg", (0, -0.42, 0)),
               (f"{_side}_foot", f"{_side}_leg", (0, -0.42, 0)),
               (f"{_side}_toe", f"{_side}_foot", (0, -0.06, 0.12)),
               (f"{_side}_toe_end", f"{_side}_toe", (0, 0, 0.05)),
               (f"{_side}_shoulder", "spine2", (_sign * 0.05, 0.1, 0)),
               (f"{_side}_arm", f"{_side}_shoulder", (_sign * 0.12, 0, 0)),
               (f"{_side}_forearm", f"{_side}_arm", (_sign * 0.27, 0, 0)),
               (f"{_side}_hand", f"{_side}_forearm", (_sign * 0.25, 0, 0)),
               (f"{_side}_hand_end", f"{_side}_hand", (_sign * 0.08, 0, 0))]


def _sided(pattern):
    """Return names of both sides: pattern(side word, 'Left'/'Right', 'L'/'R')."""
    return {key: name for side, word, letter in (("left", "Left", "L"), ("right", "Right", "R"))
            for key, name in pattern(side, word, letter).items()}


_MIXAMO_NAMES = {"hips": "Hips", "spine": "Spine", "spine1": "Spine1", "spine2": "Spine2",
                 "neck": "Neck", "head": "Head",
                 **_sided(lambda s, w, _: {f"{s}_upleg": f"{w}UpLeg", f"{s}_leg": f"{w}Leg",
                                           f"{s}_foot": f"{w}Foot", f"{s}_toe": f"{w}ToeBase",
                                           f"{s}_shoulder": f"{w}Shoulder", f"{s}_arm": f"{w}Arm",
                                           f"{s}_forearm": f"{w}ForeArm",
                                           f"{s}_hand": f"{w}Hand"})}
_LAFAN1_NAMES = {**_MIXAMO_NAMES, **_sided(lambda s, w, _: {f"{s}_toe": f"{w}Toe"})}
_BANDAI_NAMES = {"hips": "Hips", "spine": "Spine", "spine2": "Chest", "neck": "Neck",
                 "head": "Head",
                 **_sided(lambda s, _, l: {f"{s}_upleg": f"UpperLeg_{l}", f"{s}_leg": f"LowerLeg_{l}",
                                           f"{s}_foot": f"Foot_{l}", f"{s}_toe": f"Toes_{l}",
                                           f"{s}_shoulder": f"Shoulder_{l}",
                                           f"{s}_arm": f"UpperArm_{l}",
                                           f"{s}_forearm": f"LowerArm_{l}",
                                           f"{s}_hand": f"Hand_{l}"})}
_CMU_NAMES = {"hips": "Hips", "spine": "LowerBack", "spine1": "Spine", "spine2": "Spine1",
              "neck": "Neck", "head": "Head",
              **_sided(lambda s, w, _: {f"{s}_upleg": f"{w}UpLeg", f"{s}_leg": f"{w}Leg",
                                        f"{s}_foot": f"{w}Foot", f"{s}_toe": f"{w}ToeBase",
                                        f"{s}_shoulder": f"{w}Shoulder", f"{s}_arm": f"{w}Arm",
                                        f"{s}_forearm": f"{w}ForeArm", f"{s}_hand": f"{w}Hand"})}
_SMPL_NAMES = {"hips": "Pelvis", "spine": "Spine1", "spine1": "Spine2", "spine2": "Spine3",
               "neck": "Neck", "head": "Head",
               **_sided(lambda s, w, _: {f"{s}_upleg": f"{w}_hip", f"{s}_leg": f"{w}_knee",
                                         f"{s}_foot": f"{w}_ankle", f"{s}_toe": f"{w}_foot",
                                         f"{s}_shoulder": f"{w}_collar",
                                         f"{s}_arm": f"{w}_shoulder",
                                         f"{s}_forearm": f"{w}_elbow", f"{s}_hand": f"{w}_wrist"})}
_BLENDER_NAMES = {"hips": "hips", "spine": "spine", "spine2": "chest", "neck": "neck",
                  "head": "head",
                  **_sided(lambda s, _, l: {f"{s}_upleg": f"thigh.{l}", f"{s}_leg": f"shin.{l}",
                                            f"{s}_foot": f"foot.{l}", f"{s}_toe": f"toe.{l}",
                                            f"{s}_shoulder": f"shoulder.{l}",
                                            f"{s}_arm": f"upper_arm.{l}",
                                            f"{s}_forearm": f"forearm.{l}",
                                            f"{s}_hand": f"hand.{l}"})}

ZYX, ZXY, XYZ = "Zrotation Yrotation Xrotation", "Zrotation Xrotation Yrotation", \
    "Xrotation Yrotation Zrotation"
POSITIONS = "Xposition Yposition Zposition"
# name: joint names, metres per unit, root OFFSET ('zero' or 'rest': the rest hip height),
# six channels on every joint, rotation order, a locator root, a prefix, End Site names.
LAYOUTS = {
    "mixamo": dict(names={**_MIXAMO_NAMES, "head_end": "HeadTop_End"}, unit=0.01, root="rest",
                   all6=False, order=ZXY, prefix="mixamorig:", smpl22=True),
    "bandai": dict(names=_BANDAI_NAMES, unit=0.01, root="rest", all6=True, order=ZXY,
                   locator="joint_Root", smpl22=True),
    "cmu": dict(names=_CMU_NAMES, unit=0.0254 / 0.45, root="zero", all6=False, order=ZYX,
                smpl22=False),
    "lafan1": dict(names=_LAFAN1_NAMES, unit=0.01, root="rest", all6=False, order=ZYX,
                   smpl22=True),
    "momask_joints2bvh": dict(names={**_LAFAN1_NAMES}, unit=1.0, root="zero", all6=False,
                              order=ZYX, smpl22=True),
    "smpl2bvh": dict(names=_SMPL_NAMES, unit=0.01, root="rest", all6=False, order=ZYX,
                     smpl22=True),
    "blender": dict(names=_BLENDER_NAMES, unit=1.0, root="rest", all6=True, order=XYZ,
                    smpl22=False),
    "motionbuilder": dict(names=_MIXAMO_NAMES, unit=0.01, root="rest", all6=False, order=ZXY,
                          prefix="Character1_", smpl22=True),
}


def _merged(names):
    """Return [(name or None for an End Site, parent index, offset metres)] of the figure
    with the joints ``names`` lacks merged into their children."""
    places = {}
    for key, parent, offset in FIGURE:
        places[key] = np.array(offset, float) + (places[parent] if parent else 0.0)
    kept, index = [], {}
    for key, parent, _ in FIGURE:
        if key not in names and not key.endswith("_end"):
            continue
        up = parent
        while up is not None and up not in names:
            up = next(p for k, p, _ in FIGURE if k == up)
        offset = places[key] - (places[up] if up else 0.0)
        index[key] = len(kept)
        kept.append((names.get(key), key, index[up] if up else -1, offset))
    return kept


def write(path, layout: str, frames: int = 4, lift: float = 0.0):
    """Write the figure walking forward (the root turning, the left knee bending) in a
    layout of :data:`LAYOUTS`; ``lift`` raises it off the floor (metres)."""
    spec = LAYOUTS[layout]
    unit, prefix, order = spec["unit"], spec.get("prefix", ""), spec["order"]
    joints = _merged(spec["names"])
    locator = spec.get("locator")
    children = {}
    for i, (_, _, parent, _) in enumerate(joints):
        children.setdefault(parent, []).append(i)
    lines, channel_of = ["HIERARCHY"], []
    if locator:
        lines += [f"ROOT {locator}", "{", "  OFFSET 0 0 0",
                  f"  CHANNELS 6 {POSITIONS} {order}" if spec["all6"] else "  CHANNELS 0"]
        channel_of.append(("locator", 6 if spec["all6"] else 0))

    def offset_of(i):
        _, key, parent, offset = joints[i]
        if parent < 0 and spec["root"] == "zero":
            return np.zeros(3)
        return offset / unit

    def block(i, depth):
        name, key, parent, offset = joints[i]
        tab = "  " * depth
        if name is None:
            lines.extend([f"{tab}End Site", f"{tab}{{",
                          f"{tab}  OFFSET {' '.join(f'{v:.6f}' for v in offset / unit)}",
                          f"{tab}}}"])
            return
        root = parent < 0 and not locator
        lines.append(f"{tab}{'ROOT' if root else 'JOINT'} {prefix}{name}")
        lines.append(f"{tab}{{")
        lines.append(f"{tab}  OFFSET {' '.join(f'{v:.6f}' for v in offset_of(i))}")
        six = parent < 0 or spec["all6"]
        lines.append(f"{tab}  CHANNELS {6 if six else 3} {POSITIONS + ' ' if six else ''}{order}")
        channel_of.append((i, 6 if six else 3))
        kids = children.get(i, [])
        for child in kids:
            block(child, depth + 1)
        if not kids:
            lines.extend([f"{tab}  End Site", f"{tab}  {{", f"{tab}    OFFSET 0 0 0", f"{tab}  }}"])
        lines.append(f"{tab}}}")

    if locator:
        block(0, 1)
        lines.append("}")
    else:
        block(0, 0)
    axes = order.split()
    rows = []
    for t in range(frames):
        row = []
        for which, count in channel_of:
            if which == "locator":
                row += [0.0] * count
                continue
            _, key, parent, offset = joints[which]
            turn = {"X": 0.0, "Y": 0.0, "Z": 0.0}
            if parent < 0:
                position = np.array([0.0, HIP_HEIGHT + lift + 0.02 * np.sin(t), 0.3 * t]) / unit
                turn["Y"] = 15.0 * t
            else:
                position = offset / unit
                if key == "left_leg":
                    turn["X"] = 5.0 * t
            if count == 6:
                row += list(position)
            row += [turn[axis[0]] for axis in axes]
        rows.append(" ".join(f"{v:.6f}" for v in row))
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: 0.033333"] + rows
    path.write_text("\n".join(lines) + "\n")
    return path

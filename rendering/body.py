"""An SMPL-like body shaped around a skeleton's bones, built from swept tubes.

The trunk, neck, head, legs, arms, feet and hands are closed tubes (see
:mod:`rendering.tubes`) through the joints and a few points placed from them (heels,
toes, finger tips, the head's centre). Limbs bend smoothly through knees and elbows and
overlap the trunk, feet and hands where they meet, so no joint shows a gap. Lengths come
from the joints; thicknesses scale with the clip's median leg length, so a body is
fitted to its skeleton once per clip and does not pulse with noisy bone lengths.
Skeletons without a layout get a rounded tube per bone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from motion.skeletons import Skeleton
from rendering.tubes import Tube, TubeSet

SIDES = ("left", "right")


@dataclass(frozen=True)
class Layout:
    """Which joints of a skeleton carry which body parts (joint names; left before right).

    ``trunk`` lists the joints between the hips and the base of the neck, bottom up,
    without those two; ``head_lift`` places the head's centre beyond the head joint,
    along the neck, in leg lengths. ``toes`` and ``hands`` name the joints at the ball of
    each foot and the knuckles, when the skeleton has them.
    """

    hips: tuple[str, str]
    shoulders: tuple[str, str]
    trunk: tuple[str, ...]
    neck: str
    head: str
    head_lift: float
    legs: tuple[tuple[str, str, str], tuple[str, str, str]]
    arms: tuple[tuple[str, str, str], tuple[str, str, str]]
    toes: tuple[str, str] | None = None
    hands: tuple[str, str] | None = None


LAYOUTS = {
    "h36m17": Layout(
        hips=("LHip", "RHip"),
        shoulders=("LShoulder", "RShoulder"),
        trunk=("Spine",),
        neck="Thorax",
        head="Head",
        head_lift=-0.085,  # Human3.6M's head joint is near the crown
        legs=(("LHip", "LKnee", "LFoot"), ("RHip", "RKnee", "RFoot")),
        arms=(("LShoulder", "LElbow", "LWrist"), ("RShoulder", "RElbow", "RWrist")),
    ),
    "humanact12": Layout(
        hips=("left_hip", "right_hip"),
        shoulders=("left_shoulder", "right_shoulder"),
        trunk=("spine2",),
        neck="neck",
        head="head",
        head_lift=0.045,  # SMPL's head joint is low in the skull
        legs=(("left_hip", "left_knee", "left_ankle"), ("right_hip", "right_knee", "right_ankle")),
        arms=(("left_shoulder", "left_elbow", "left_wrist"),
              ("right_shoulder", "right_elbow", "right_wrist")),
        toes=("left_foot", "right_foot"),
        hands=("left_hand", "right_hand"),
    ),
    "kit21": Layout(
        hips=("left_hip", "right_hip"),
        shoulders=("left_shoulder", "right_shoulder"),
        trunk=("chest",),
        neck="neck",
        head="head",
        head_lift=0.03,  # KIT's head joint sits at the top of the neck
        legs=(("left_hip", "left_knee", "left_ankle"), ("right_hip", "right_knee", "right_ankle")),
        arms=(("left_shoulder", "left_elbow", "left_wrist"),
              ("right_shoulder", "right_elbow", "right_wrist")),
        toes=("left_foot", "right_foot"),
    ),
}
LAYOUTS["smpl24"] = LAYOUTS["humanact12"]  # the same 24 SMPL joints
# HumanML3D's 22: SMPL's without the hand joints.
LAYOUTS["smpl22"] = replace(LAYOUTS["humanact12"], hands=None)

# Half-thicknesses and offsets in leg lengths (hip to ankle, about 0.45 of the stature).
LEG = ((0.0, 0.07), (0.22, 0.086), (0.5, 0.076), (1.0, 0.056), (1.3, 0.064), (2.0, 0.039))
ARM = ((0.0, 0.058), (0.4, 0.05), (1.0, 0.04), (1.25, 0.045), (2.0, 0.03))
NECK = 0.06
HEAD = (0.092, 0.108, 0.132)  # across, front to back, up
FOOT_TILT = np.radians(24.0)  # the ankle-to-ball line slopes down this much on a flat foot
# (along the foot, below its axis, across, height) at heel, ball and toe tip.
FOOT = ((-0.075, 0.035, 0.042, 0.034), (0.16, 0.05, 0.052, 0.022), (0.25, 0.055, 0.04, 0.015))
HAND = ((0.0, 0.032, 0.024), (0.1, 0.048, 0.022), (0.19, 0.038, 0.018))  # along, across, thick
TRUNK_DEPTH = (0.1, 0.115, 0.1, 0.12, 0.1, 0.075)  # at the stations of the trunk's widths
BONE = 0.05  # half-thickness of the tubes of skeletons without a layout, in leg lengths


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.maximum(np.linalg.norm(vectors, axis=-1, keepdims=True), 1e-12)


def _square(vector: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Return the unit part of ``vector`` square to the unit ``axis``."""
    return _unit(vector - np.dot(vector, axis) * axis)


class Body:
    """A body fitted to one clip's joints ``(T, J, 3)``, z up; ``pose`` places it per frame."""

    def __init__(self, skeleton: Skeleton, joints: np.ndarray):
        self.skeleton = skeleton
        self.layout = LAYOUTS.get(skeleton.family)
        self._index = {name: j for j, name in enumerate(skeleton.joint_names)}
        joints = np.asarray(joints, dtype=np.float64)
        if self.layout is None:
            tubes, extra, vectors = self._bone_tubes(joints)
        else:
            tubes, extra, vectors = self._body_tubes(joints)
        names = list(skeleton.joint_names) + extra  # placed points start with "+"
        self.tubes = TubeSet(tubes, {n: i for i, n in enumerate(names)},
                             {n: i for i, n in enumerate(vectors)})
        self.faces = self.tubes.faces
        self.n_vertices = self.tubes.n_vertices
        self.pieces = [tube.name for tube in tubes]
        self.sides = np.empty(self.n_vertices, dtype=object)
        for number, tube in enumerate(tubes):
            self.sides[self.tubes.piece(number)[0]] = tube.side
        self.key = (skeleton.name, self.n_vertices)

    def lift(self, height: float) -> None:
        """Do nothing: this body follows the joints it is posed with, raised or not."""

    def pose_at(self, number: int, joints: np.ndarray):
        """Return :meth:`pose` of a frame's joints (the frame's number is not needed)."""
        return self.pose(joints)

    def pose(self, joints: np.ndarray):
        """Return vertices and normals ``(V, 3)``, ring centres ``(R, 3)`` and radii ``(R,)``."""
        joints = np.asarray(joints, dtype=np.float64)
        if self.layout is None:
            points, vectors = joints, self._bone_vectors(joints)
        else:
            extra, vectors = self._places(joints)
            points = np.concatenate([joints, extra])
        return self.tubes.pose(points, vectors)

    # Skeletons with a layout: a human body.

    def _body_tubes(self, joints: np.ndarray):
        """Return the tubes of a human body fitted to these joints, and the names they use."""
        layout, index = self.layout, self._index
        legs = [[index[n] for n in leg] for leg in layout.legs]
        lengths = [np.linalg.norm(joints[:, a] - joints[:, b], axis=-1)
                   for leg in legs for a, b in zip(leg, leg[1:])]
        self.unit = float(np.median(np.sum(lengths, axis=0) / 2)) or 1.0
        hip_span, shoulder_span = (
            float(np.median(np.linalg.norm(joints[:, index[a]] - joints[:, index[b]], axis=-1))) / 2
            for a, b in (layout.hips, layout.shoulders)
        )
        u = self.unit
        pelvis = max(0.17 * u, hip_span + 0.075 * u)
        chest = max(0.15 * u, shoulder_span - 0.005 * u)
        trunk_path = ("+bottom", "+pelvis", *layout.trunk, "+chest", layout.neck)
        top = len(trunk_path) - 1.0
        # Bottom, hips, waist, chest at the shoulders, the shoulders' top, the neck's base.
        stations = (0.0, 1.0, top - 2.0, top - 1.0, top - 0.45, top)
        widths = (0.9 * pelvis, pelvis, 0.44 * (pelvis + chest), chest, 0.9 * chest, 0.5 * chest)
        tubes = [Tube(
            "trunk", "centre", trunk_path,
            tuple((s, w, d * u) for s, w, d in zip(stations, widths, TRUNK_DEPTH)),
            ((1.0, "hips"), (top - 1.0, "shoulders")),
            (0.08 * u, 0.03 * u), rings=4, exponent=2.5,
        ), Tube(
            "neck", "centre", (layout.neck, "+head_low"), ((0.0, NECK * u, NECK * u),),
            ((0.0, "shoulders"),), (0.02 * u, 0.02 * u), rings=2, cap_rings=(0, 0),
        ), Tube(
            "head", "centre", ("+head_low", "+head_high"),
            ((0.0, HEAD[0] * u, HEAD[1] * u),), ((0.0, "shoulders"),),
            ((HEAD[2] - 0.03) * u, (HEAD[2] - 0.03) * u), rings=2, cap_rings=(4, 4),
        )]
        for side, leg, arm in zip(SIDES, layout.legs, layout.arms):
            tubes.append(Tube(
                f"{side}_leg", side, leg, tuple((s, r * u, r * u) for s, r in LEG),
                ((0.0, f"{side}_leg_bend"),), (LEG[0][1] * u, 0.035 * u), rings=6, cap_rings=(2, 2),
            ))
            tubes.append(Tube(
                f"{side}_arm", side, arm, tuple((s, r * u, r * u) for s, r in ARM),
                ((0.0, f"{side}_arm_bend"),), (ARM[0][1] * u, 0.015 * u), rings=6,
                cap_rings=(3, 0),
            ))
            tubes.append(Tube(
                f"{side}_foot", side, (f"+{side}_heel", f"+{side}_ball", f"+{side}_tip"),
                tuple((k, w * u, h * u) for k, (_, _, w, h) in enumerate(FOOT)),
                ((0.0, f"{side}_foot"),), (0.035 * u, 0.035 * u), rings=3, exponent=2.4,
            ))
            tubes.append(Tube(
                f"{side}_hand", side, (arm[2], f"+{side}_knuckles", f"+{side}_fingers"),
                tuple((k, w * u, t * u) for k, (_, w, t) in enumerate(HAND)),
                ((0.0, "forward"),), (0.01 * u, 0.03 * u), rings=3, cap_rings=(0, 3),
            ))
        extra = ["+bottom", "+pelvis", "+chest", "+head_low", "+head_high"]
        for side in SIDES:
            extra += [f"+{side}_heel", f"+{side}_ball", f"+{side}_tip", f"+{side}_knuckles",
                      f"+{side}_fingers"]
        vectors = ["hips", "shoulders", "forward"]
        for side in SIDES:
            vectors += [f"{side}_leg_bend", f"{side}_arm_bend", f"{side}_foot"]
        return tubes, extra, vectors

    def _places(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the placed points and the across directions of one pose ``(J, 3)``."""
        layout, index, u = self.layout, self._index, self.unit
        at = {name: joints[j] for name, j in index.items()}
        pelvis = (at[layout.hips[0]] + at[layout.hips[1]]) / 2
        chest = (at[layout.shoulders[0]] + at[layout.shoulders[1]]) / 2
        trunk_up = _unit(chest - pelvis)
        hips = _unit(at[layout.hips[0]] - at[layout.hips[1]])
        shoulders = _unit(at[layout.shoulders[0]] - at[layout.shoulders[1]])
        forward = _unit(np.cross(hips + shoulders, trunk_up))
        neck_up = _unit(at[layout.head] - at[layout.neck])
        head = at[layout.head] + layout.head_lift * u * neck_up
        points = [pelvis - 0.06 * u * trunk_up, pelvis, chest,
                  head - 0.03 * u * neck_up, head + 0.03 * u * neck_up]
        vectors = [hips, shoulders, forward]
        for number, side in enumerate(SIDES):
            hip, knee, ankle = (at[n] for n in layout.legs[number])
            shoulder, elbow, wrist = (at[n] for n in layout.arms[number])
            ahead, below = self._foot_axes(number, at, forward)
            points += [ankle + along * u * ahead + drop * u * below for along, drop, _, _ in FOOT]
            forearm = _unit(wrist - elbow)
            if layout.hands:
                knuckles = at[layout.hands[number]]
                hand = _unit(knuckles - wrist)
                reach = HAND[2][0] - HAND[1][0]
                points += [knuckles, knuckles + reach * u * hand]
            else:
                points += [wrist + HAND[1][0] * u * forearm, wrist + HAND[2][0] * u * forearm]
            vectors += [self._bend(hip, knee, ankle, hips),
                        self._bend(shoulder, elbow, wrist, shoulders), np.cross(below, ahead)]
        return np.array(points), np.array(vectors)

    def _foot_axes(self, number: int, at: dict, forward) -> tuple[np.ndarray, np.ndarray]:
        """Return the directions along a foot (heel to toe) and down through its sole."""
        _, knee, ankle = (at[n] for n in self.layout.legs[number])
        down = np.array([0.0, 0.0, -1.0])
        if self.layout.toes:  # the ankle-to-ball line, turned up by the foot's usual slope
            ball = _unit(at[self.layout.toes[number]] - ankle)
            side = _unit(np.cross(ball, down))
            below = np.cross(side, ball)
            ahead = np.cos(FOOT_TILT) * ball - np.sin(FOOT_TILT) * below
            return ahead, _unit(np.cross(side, ahead))
        # Without toes the foot points where the body faces, pitched half as much as the shin.
        level = forward * [1.0, 1.0, 0.0]
        if np.linalg.norm(level) < 1e-6:
            level = np.array([1.0, 0.0, 0.0])
        level = _unit(level)
        shin = _unit(ankle - knee)
        rigid = level - np.dot(level, shin) * shin
        ahead = _unit(level + _unit(rigid))
        return ahead, _square(down, ahead)

    @staticmethod
    def _bend(start, middle, end, fallback) -> np.ndarray:
        """Return the normal of a limb's bend; a straight limb uses a square to ``fallback``."""
        upper, lower = middle - start, end - middle
        normal = np.cross(upper, lower)
        if np.linalg.norm(normal) < 0.05 * np.linalg.norm(upper) * np.linalg.norm(lower):
            normal = np.cross(upper, fallback)
        return normal

    # Skeletons without a layout: a rounded tube along every bone.

    def _bone_tubes(self, joints: np.ndarray):
        """Return one rounded tube per bone, as thick as a limb of a body this tall."""
        heights = joints[..., 2].max(axis=1) - joints[..., 2].min(axis=1)
        self.unit = 0.5 * float(np.median(heights)) or 1.0
        radius = BONE * self.unit
        names = self.skeleton.joint_names
        # Bones without length (joints at one place, as some BVH hierarchies have) get no tube.
        self._bones = [(parent, child) for parent, child in self.skeleton.bones
                       if np.median(np.linalg.norm(joints[:, child] - joints[:, parent],
                                                   axis=-1)) > 1e-3 * self.unit]
        tubes = [
            Tube(f"bone_{names[child]}", self.skeleton.side_of(child),
                 (names[parent], names[child]), ((0.0, radius, radius),),
                 ((0.0, f"bone_{child}"),), (radius, radius), rings=2)
            for parent, child in self._bones
        ]
        vectors = [f"bone_{child}" for _, child in self._bones]
        return tubes, [], vectors

    def _bone_vectors(self, joints: np.ndarray) -> np.ndarray:
        """Return a direction square to each bone (bone tubes are round: any will do)."""
        bones = np.array(self._bones).reshape(-1, 2)
        along = joints[bones[:, 1]] - joints[bones[:, 0]]
        axis = np.eye(3)[np.argmin(np.abs(along), axis=1)]
        across = np.cross(along, axis)
        # A bone that has no length in this frame keeps some direction square to nothing.
        return np.where(np.linalg.norm(across, axis=1, keepdims=True) > 1e-12, across, axis)

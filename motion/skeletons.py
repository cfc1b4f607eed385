"""Named skeletons as data: joint names, parents, sides, up axis, units.

The built-in skeletons are registered when this module is imported. Files that bring
their own hierarchy (a BVH file, an interchange file written from one) get a *custom*
skeleton from :func:`custom_skeleton`, named by a hash of its definition so that the
same hierarchy always gets the same name; :func:`list_skeletons` lists the built-in
ones only.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, replace

import numpy as np

from motion.registry import Registry


@dataclass(frozen=True)
class Skeleton:
    """A kinematic tree.

    ``parents[j]`` is the parent joint of ``j`` (``-1`` for the root). ``left`` and
    ``right`` list the joints of each side (for colours and mirroring). ``up`` names the
    vertical axis: ``"z"``, ``"y"`` or ``"-y"`` (image coordinates, y pointing down).
    ``chains`` are the kinematic chains from the root outwards (A2M's five chains).
    ``units`` names the coordinate unit: ``"m"``, ``"mm"`` or ``"px"`` (2D images).
    ``base`` is, for a skeleton re-expressed in other axes or units, the name of the
    skeleton it came from (its joints are the same; body layouts are looked up by it).
    """

    name: str
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    left: tuple[int, ...]
    right: tuple[int, ...]
    up: str
    dims: int
    chains: tuple[tuple[int, ...], ...]
    description: str = ""
    units: str = "m"
    base: str = ""

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def root(self) -> int:
        return self.parents.index(-1)

    @property
    def bones(self) -> list[tuple[int, int]]:
        """Return the (parent, child) pairs."""
        return [(p, j) for j, p in enumerate(self.parents) if p >= 0]

    @property
    def up_index(self) -> int:
        return "xyz".index(self.up[-1])

    @property
    def up_sign(self) -> float:
        return -1.0 if self.up.startswith("-") else 1.0

    @property
    def metres_per_unit(self) -> float | None:
        """Return metres per coordinate unit (``None`` for pixels)."""
        return UNITS[self.units]

    @property
    def family(self) -> str:
        """Return the name of the skeleton these joints were first defined for."""
        return self.base or self.name

    def side_of(self, joint: int) -> str:
        """Return ``"left"``, ``"right"`` or ``"centre"`` for a joint."""
        if joint in self.left:
            return "left"
        if joint in self.right:
            return "right"
        return "centre"

    def bone_lengths(self, joints: np.ndarray) -> np.ndarray:
        """Return bone lengths of joints ``(..., J, D)`` as ``(..., J)`` (root: 0)."""
        parents = np.array([max(p, 0) for p in self.parents])
        lengths = np.linalg.norm(joints - joints[..., parents, :], axis=-1)
        lengths[..., self.root] = 0.0
        return lengths

    def index(self, joint_name: str) -> int:
        """Return the index of a joint by name."""
        try:
            return self.joint_names.index(joint_name)
        except ValueError:
            raise KeyError(
                f"skeleton {self.name!r} has no joint {joint_name!r}; "
                f"its joints are {', '.join(self.joint_names)}"
            ) from None


def _chains(parents: tuple[int, ...]) -> tuple[tuple[int, ...], ...]:
    """Split a tree into chains: each starts at a branching joint and runs to a leaf."""
    children: dict[int, list[int]] = {}
    for joint, parent in enumerate(parents):
        children.setdefault(parent, []).append(joint)
    root = parents.index(-1)
    chains = []
    for first in children.get(root, []):
        chain = [root, first]
        while len(children.get(chain[-1], [])) == 1:
            chain.append(children[chain[-1]][0])
        chains.append(tuple(chain))
        for branch in children.get(chain[-1], []):
            stack = [(chain[-1], branch)]
            while stack:
                start, nxt = stack.pop()
                sub = [start, nxt]
                while len(children.get(sub[-1], [])) == 1:
                    sub.append(children[sub[-1]][0])
                chains.append(tuple(sub))
                stack.extend((sub[-1], c) for c in children.get(sub[-1], []))
    return tuple(chains)


UNITS = {"m": 1.0, "mm": 0.001, "px": None}
UP_AXES = ("x", "y", "z", "-x", "-y", "-z")

_REGISTRY = Registry("skeleton")
_CUSTOM: set[str] = set()


def _check(skeleton: Skeleton) -> None:
    if len(skeleton.parents) != len(skeleton.joint_names):
        raise ValueError(f"skeleton {skeleton.name!r}: one parent per joint is needed")
    if skeleton.up not in UP_AXES:
        raise ValueError(f"skeleton {skeleton.name!r}: up must be one of {UP_AXES}")
    if skeleton.units not in UNITS:
        raise ValueError(f"skeleton {skeleton.name!r}: units must be one of {tuple(UNITS)}")
    parents = skeleton.parents
    roots = [j for j, p in enumerate(parents) if p < 0]
    if len(roots) != 1 or any(p >= len(parents) for p in parents):
        raise ValueError(f"skeleton {skeleton.name!r}: one root and valid parents are needed")
    for joint in range(len(parents)):
        steps = 0
        while joint >= 0 and steps <= len(parents):
            joint, steps = parents[joint], steps + 1
        if steps > len(parents):
            raise ValueError(f"skeleton {skeleton.name!r}: the parents form a cycle")


def register_skeleton(skeleton: Skeleton) -> Skeleton:
    """Add a skeleton to the registry (its name must be new)."""
    if skeleton.name in _REGISTRY:
        raise ValueError(f"skeleton {skeleton.name!r} is already registered")
    _check(skeleton)
    return _REGISTRY.add(skeleton.name, skeleton)


def register_custom(skeleton: Skeleton) -> Skeleton:
    """Add a custom skeleton, or return the registered one of the same definition."""
    if skeleton.name in _REGISTRY:
        known = _REGISTRY.get(skeleton.name)
        if replace(known, description="") != replace(skeleton, description=""):
            raise ValueError(f"skeleton {skeleton.name!r} is registered with another "
                             "definition")
        return known
    _check(skeleton)
    _REGISTRY.add(skeleton.name, skeleton)
    _CUSTOM.add(skeleton.name)
    return skeleton


def is_custom(name: str) -> bool:
    """Return whether a skeleton was made from a file's own hierarchy (or derived)."""
    return name in _CUSTOM


def side_of_name(name: str) -> str:
    """Guess a joint's side from its name: ``LeftArm``, ``l_hip``, ``LHipJoint``, ``Right_knee``,
    ``UpperLeg_L``, ``thigh.R``."""
    plain = name.rsplit(":", 1)[-1]
    lower = plain.lower()
    if lower.startswith("left") or re.match(r"^[Ll](?:[A-Z_\-. ]|$)", plain):
        return "left"
    if lower.startswith("right") or re.match(r"^[Rr](?:[A-Z_\-. ]|$)", plain):
        return "right"
    suffix = re.search(r"[_\-. ]([LlRr])$", plain)  # Bandai's UpperLeg_L, Blender's thigh.L
    if suffix:
        return "left" if suffix.group(1) in "Ll" else "right"
    if "left" in lower:
        return "left"
    if "right" in lower:
        return "right"
    return "centre"


def custom_skeleton(joint_names, parents, up: str = "y", units: str = "m",
                    prefix: str = "custom", sides=None, description: str = "") -> Skeleton:
    """Return the registered skeleton of a file's own hierarchy (3D), registering it once.

    ``sides`` gives each joint's side (default: guessed from its name, see
    :func:`side_of_name`). The name is ``<prefix>_<hash>`` of the whole definition.
    """
    joint_names = tuple(str(n) for n in joint_names)
    parents = tuple(int(p) for p in parents)
    sides = tuple(sides) if sides is not None else tuple(side_of_name(n) for n in joint_names)
    if len(sides) != len(joint_names):
        raise ValueError("one side per joint is needed")
    digest = hashlib.sha256(repr((joint_names, parents, up, units, sides)).encode()).hexdigest()
    skeleton = Skeleton(
        name=f"{prefix}_{digest[:10]}",
        joint_names=joint_names,
        parents=parents,
        left=tuple(i for i, side in enumerate(sides) if side == "left"),
        right=tuple(i for i, side in enumerate(sides) if side == "right"),
        up=up,
        dims=3,
        chains=_chains(parents),
        description=description or f"{len(joint_names)} joints of a file's own hierarchy",
        units=units,
    )
    return register_custom(skeleton)


def sides_of(skeleton: Skeleton) -> tuple[str, ...]:
    """Return each joint's side, ``left``/``right``/``centre``."""
    return tuple(skeleton.side_of(j) for j in range(skeleton.n_joints))


def canonical_skeleton(skeleton: Skeleton) -> Skeleton:
    """Return the skeleton with the same joints, z up and in metres (itself if it is)."""
    if skeleton.dims != 3 or (skeleton.up == "z" and skeleton.units == "m"):
        return skeleton
    name = f"{skeleton.family}@z_up_m"
    return register_custom(replace(skeleton, name=name, up="z", units="m",
                                   base=skeleton.family,
                                   description=f"{skeleton.family}, z up, metres"))


def flat_skeleton(skeleton: Skeleton) -> Skeleton:
    """Return the 2D skeleton of a 3D one seen from the front (across, up; metres)."""
    if skeleton.dims == 2:
        return skeleton
    name = f"{skeleton.family}@front_2d"
    return register_custom(replace(skeleton, name=name, up="y", units="m", dims=2,
                                   base=skeleton.family,
                                   description=f"{skeleton.family} seen from the front, 2D"))


def get_skeleton(name: str) -> Skeleton:
    """Return a registered skeleton by name."""
    return _REGISTRY.get(name)


def list_skeletons() -> list[str]:
    """Return the names of the built-in skeletons (not those made from files)."""
    return sorted(set(_REGISTRY.names()) - _CUSTOM)


def _skeleton(name, joint_names, parents, up, dims, description, units="m"):
    left = tuple(i for i, n in enumerate(joint_names) if n.startswith(("L", "left_")))
    right = tuple(i for i, n in enumerate(joint_names) if n.startswith(("R", "right_")))
    parents = tuple(parents)
    return register_skeleton(
        Skeleton(
            name=name,
            joint_names=tuple(joint_names),
            parents=parents,
            left=left,
            right=right,
            up=up,
            dims=dims,
            chains=_chains(parents),
            description=description,
            units=units,
        )
    )


H36M17 = _skeleton(
    "h36m17",
    ["Hip", "RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot", "Spine", "Thorax",
     "Neck/Nose", "Head", "LShoulder", "LElbow", "LWrist", "RShoulder", "RElbow", "RWrist"],
    [-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15],
    up="z",
    dims=3,
    description="Human3.6M, the 17 moving joints of the 32-joint layout; metres, z up",
)

# Indices of the h36m17 joints in the original 32-joint Human3.6M layout.
H36M32_TO_17 = (0, 1, 2, 3, 6, 7, 8, 12, 13, 14, 15, 17, 18, 19, 25, 26, 27)

# The 2D setting of seeds 003/004: h36m17 without Hip and Neck/Nose (their code keeps
# these 15), projected onto camera 55011271, pixels with y down. Spine becomes the root.
H36M15_2D_FROM_17 = (1, 2, 3, 4, 5, 6, 7, 8, 10, 11, 12, 13, 14, 15, 16)

H36M15_2D = _skeleton(
    "h36m15_2d",
    ["RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot", "Spine", "Thorax", "Head",
     "LShoulder", "LElbow", "LWrist", "RShoulder", "RElbow", "RWrist"],
    [6, 0, 1, 6, 3, 4, -1, 6, 7, 7, 9, 10, 7, 12, 13],
    up="-y",
    dims=2,
    units="px",
    description="Human3.6M in 2D as in seeds 003/004: 15 joints (Hip and Neck/Nose "
    "dropped), projected with camera 55011271; pixels, y down",
)

HUMANACT12 = _skeleton(
    "humanact12",
    ["pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
     "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck",
     "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
     "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hand", "right_hand"],
    [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21],
    up="y",
    dims=3,
    description="HumanAct12 / SMPL, 24 joints in SMPL order; metres, y up",
)

# SMPL's 24 joints in SMPL order, shared by smpl24 and (its first 22) smpl22.
SMPL_JOINTS = HUMANACT12.joint_names
SMPL_PARENTS = HUMANACT12.parents

SMPL24 = _skeleton(
    "smpl24",
    SMPL_JOINTS,
    SMPL_PARENTS,
    up="y",
    dims=3,
    description="SMPL's 24 joints (MDM's and ACTOR's action models, MotionCritic); metres, y up",
)

SMPL22 = _skeleton(
    "smpl22",
    SMPL_JOINTS[:22],
    SMPL_PARENTS[:22],
    up="y",
    dims=3,
    description="HumanML3D / t2m: SMPL's first 22 joints (no hands), as MDM, MoMask, "
    "T2M-GPT, MotionGPT and MotionDiffuse write them; metres, y up",
)

# KIT-ML as HumanML3D processes it: kinematic chains [0, 11..15] (right leg),
# [0, 16..20] (left leg), [0, 1..4] (spine to head), [3, 5, 6, 7] (right arm) and
# [3, 8, 9, 10] (left arm); the right side lies along +x.
KIT21 = _skeleton(
    "kit21",
    ["root", "spine", "chest", "neck", "head",
     "right_shoulder", "right_elbow", "right_wrist",
     "left_shoulder", "left_elbow", "left_wrist",
     "right_hip", "right_knee", "right_ankle", "right_foot", "right_toe",
     "left_hip", "left_knee", "left_ankle", "left_foot", "left_toe"],
    [-1, 0, 1, 2, 3, 3, 5, 6, 3, 8, 9, 0, 11, 12, 13, 14, 0, 16, 17, 18, 19],
    up="y",
    dims=3,
    units="mm",
    description="KIT-ML in HumanML3D's processing: 21 joints; millimetres, y up",
)

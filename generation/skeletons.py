"""Named skeletons as data: joint names, parents, sides, up axis."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Skeleton:
    """A kinematic tree.

    ``parents[j]`` is the parent joint of ``j`` (``-1`` for the root). ``left`` and
    ``right`` list the joints of each side (for colours and mirroring). ``up`` names the
    vertical axis: ``"z"``, ``"y"`` or ``"-y"`` (image coordinates, y pointing down).
    ``chains`` are the kinematic chains from the root outwards (A2M's five chains).
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


_REGISTRY: dict[str, Skeleton] = {}


def register_skeleton(skeleton: Skeleton) -> Skeleton:
    """Add a skeleton to the registry (its name must be new)."""
    if skeleton.name in _REGISTRY:
        raise ValueError(f"skeleton {skeleton.name!r} is already registered")
    if len(skeleton.parents) != len(skeleton.joint_names):
        raise ValueError(f"skeleton {skeleton.name!r}: one parent per joint is needed")
    _REGISTRY[skeleton.name] = skeleton
    return skeleton


def get_skeleton(name: str) -> Skeleton:
    """Return a registered skeleton by name."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(
            f"unknown skeleton {name!r}; known skeletons: {', '.join(sorted(_REGISTRY))}"
        ) from None


def list_skeletons() -> list[str]:
    """Return the names of all registered skeletons."""
    return sorted(_REGISTRY)


def _skeleton(name, joint_names, parents, up, dims, description):
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

"""Training augmentation of the classifier's inputs: mirrored clips and small rotations.

The inputs are per frame the joints relative to the root and the root's path from its
start, ``(N, T, J + 1, D)`` before standardisation. Both are linear in the coordinates,
so a mirror image or a rotation of a clip is the same map applied to every row.
"""

from __future__ import annotations

import math

import torch

from motion_metrics.recognition.errors import ClassifierError
from motion.skeletons import Skeleton

SIDE_PREFIXES = (("L", "R"), ("left_", "right_"), ("Left", "Right"))


def mirror_permutation(skeleton: Skeleton) -> list[int]:
    """Return, per joint, the joint it becomes in the mirror image (left and right swapped).

    The skeleton's ``left`` and ``right`` lists pair by position; each pair's names must
    differ only by their side (``LHip``/``RHip``, ``left_hip``/``right_hip``).
    """
    if len(skeleton.left) != len(skeleton.right) or not skeleton.left:
        raise ClassifierError(f"skeleton {skeleton.name!r} has no left and right joints in pairs "
                              f"to mirror; train without mirroring (mirror: false)")
    order = list(range(skeleton.n_joints))
    for left, right in zip(skeleton.left, skeleton.right):
        a, b = skeleton.joint_names[left], skeleton.joint_names[right]
        if not any(a.startswith(l) and b.startswith(r) and a[len(l):] == b[len(r):]
                   for l, r in SIDE_PREFIXES):
            raise ClassifierError(f"skeleton {skeleton.name!r} pairs {a!r} with {b!r}, which are not "
                                  f"one joint's two sides; train without mirroring (mirror: false)")
        order[left], order[right] = right, left
    return order


class Augmenter:
    """Mirror (with probability 1/2) and rotate (uniformly within ``±degrees``) batches of inputs."""

    def __init__(self, skeleton: Skeleton, mirror: bool, degrees: float):
        self.dims = skeleton.dims
        up = skeleton.up_index
        # The horizontal plane in 3D (about the vertical axis), the image plane in 2D.
        self.plane = [axis for axis in range(self.dims) if self.dims == 2 or axis != up]
        self.lateral = self.plane[0] if self.plane[0] != up else self.plane[1]
        self.order = None
        if mirror:
            # The root's path (the last row) stays in place; joints swap sides.
            self.order = torch.tensor(mirror_permutation(skeleton) + [skeleton.n_joints])
        self.radians = math.radians(degrees)

    @property
    def active(self) -> bool:
        return self.order is not None or self.radians > 0

    def __call__(self, inputs: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Return augmented inputs ``(B, T, J + 1, D)``; the draws come from ``generator``."""
        out = inputs
        count = len(inputs)
        if self.order is not None:
            flip = torch.rand(count, generator=generator) < 0.5
            mirrored = inputs[:, :, self.order].clone()
            mirrored[..., self.lateral] = -mirrored[..., self.lateral]
            out = torch.where(flip[:, None, None, None], mirrored, inputs)
        if self.radians > 0:
            angle = (torch.rand(count, generator=generator) * 2 - 1) * self.radians
            cos, sin = torch.cos(angle)[:, None, None], torch.sin(angle)[:, None, None]
            a, b = self.plane
            rotated = out.clone()
            rotated[..., a] = cos * out[..., a] - sin * out[..., b]
            rotated[..., b] = sin * out[..., a] + cos * out[..., b]
            out = rotated
        return out

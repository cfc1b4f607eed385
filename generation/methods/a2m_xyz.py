"""Action2Motion without Lie algebra ("Ours w/o Lie", seed 000, Sec. 4.2.2): joints out directly.

The same conditional temporal VAE as :mod:`generation.methods.a2m` (prior, posterior,
two-layer generator GRU, loss Eq. 9, teacher forcing, λ, optimiser, presets), but the
generator's decoder ``D_e`` outputs the joint positions of the pose itself: no Lie
parameters, no forward kinematics, so nothing holds bone lengths constant (the
artefact seed 000 shows in Fig. 3). For HumanAct12 the decoder is the same
``Linear(128, 72)`` as A2M's; only A2M's Lie output layer is gone.

The pose vector ``p_t`` (the generator's output and its next input) is the joints
relative to the clip's first root position on the floor (height kept), standardised
per coordinate over the training frames; ``p_0 = 0`` is then the mean pose. Samples
start at the training clips' mean start, as A2M's. The loss is taken on the joints in
metre-like units, as A2M's, so λ keeps its meaning. ``rotation_frames`` of the config
has no effect here.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from generation.methods.a2m import A2M, A2MConfig, GRUGenerator
from generation.methods.base import register_method
from generation.methods.common import (
    loss_unit,
    pose_statistics,
    pose_vectors,
    relative_to_start,
)
from generation.methods.kinematics import clip_bone_lengths
from motion.skeletons import get_skeleton


@register_method("a2m_xyz")
class A2MXYZ(A2M):
    """Action2Motion's conditional temporal VAE with joint positions in place of Lie parameters."""

    Config = A2MConfig

    def build(self):
        self.pose_size = self.pose_width
        return self._vae_networks()

    def _generator(self, inputs: int) -> nn.Module:
        """Return the generator ``GRU_θ`` with ``D_e`` to the joint positions."""
        cfg = self.config
        return GRUGenerator(inputs, cfg.embed, cfg.hidden, cfg.generator_layers, self.pose_size)

    def prepare(self, clips):
        skeleton = get_skeleton(self.skeleton)
        joints = self.clip_array(clips)
        # Median bone lengths are kept for reference and for A2M's sampling path; unused by it.
        bone_lengths = np.median(clip_bone_lengths(skeleton, joints), axis=0)
        return {
            **pose_statistics(skeleton, joints),  # origin, mean and std of the pose vectors
            "bone_lengths": bone_lengths,
            "unit": loss_unit(skeleton, bone_lengths),
        }

    def encode(self, clips):
        skeleton = get_skeleton(self.skeleton)
        joints = self.clip_array(clips)
        return {
            "pose": pose_vectors(skeleton, joints, self.extras),
            "target": torch.from_numpy(relative_to_start(skeleton, joints)).float(),
            # A2M's training step passes lengths to _joints, which ignores them here.
            "lengths": torch.from_numpy(clip_bone_lengths(skeleton, joints)).float(),
            "label": self.action_indices([clip.action for clip in clips]),
        }

    def _joints(self, poses: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """Return joints ``(B, T, J, D)`` of pose vectors ``(B, T, F)``; ``lengths`` is unused."""
        skeleton = get_skeleton(self.skeleton)
        mean = torch.as_tensor(self.extras["mean"], dtype=poses.dtype)
        std = torch.as_tensor(self.extras["std"], dtype=poses.dtype)
        return (poses * std + mean).unflatten(-1, (skeleton.n_joints, skeleton.dims))

    def generate(self, labels, frames, generator):
        """Sample with the prior; the joints are the generator's outputs, bone lengths free."""
        return super().generate(labels, frames, generator)

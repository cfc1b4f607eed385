"""SkeletonGAN (Cai et al., ECCV 2018), the pose-sequence stage, as a baseline of seeds 003/004.

Two stages, as seeds 003/004 describe it ("a Single Pose Training stage and a Pose
Sequence Generation stage"; "pretraining"):

1. *Single pose training*: a conditional WGAN-GP learns a pose generator
   ``G0(z, y)`` of single frames from a latent ``z`` and the class row ``y``;
2. *Pose sequence generation*: with ``G0`` pretrained and frozen, an LSTM generates the
   path of latent poses ``z_{t+1} = z_t + Δz_t`` from the first latent ``z_1`` and
   ``y``; the poses are ``G0(z_t, y)``. A sequence discriminator ``D(x, y)`` judges
   whole motions; latent shifts and pose changes are penalised for smoothness.

What was assumed (the paper's code for this stage was not consulted here), kept
deliberately close to c-SkeletonGAN (seed 003), whose authors built on it, so the
two differ where seed 003 says they do:

- the LSTM reads ``(z_1, y)`` at every step: a motion's randomness is its first
  latent only (seed 003's implicit LSTM instead reads fresh noise per step);
- no classifier and no cycle-consistency loss (seed 003's additions);
- sizes as c-SkeletonGAN's code: latent 12, LSTM 256, ``G0`` ``12 + C -> 1024 -> BN ->
  ReLU -> pose``, critic ``pose + C -> 1024 -> 1``; WGAN-GP λ = 10, 5 critic steps,
  lr 1e-3; sequence stage lr 1e-4, Adam betas (0.5, 0.9), batch 64;
- the sequence stage is a non-saturating binary GAN with a bidirectional LSTM
  discriminator (as in that code); the smoothness terms take that code's weights:
  ``0.1 Σ ||Δz_t||² + 1e-4 Σ ||x_{t+1} - x_t||²``;
- ``z`` is standard Gaussian in both stages; the first ``pretrain_iters`` iterations of
  ``fit`` are stage 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, adam, one_hot
from generation.methods.seq_gan_common import (
    FrameCritic,
    FrameDecoder,
    LatentTransitions,
    SequenceLSTM,
    bce,
    frame_wgan_gp_step,
    latent_prior,
    smoothness,
)

BETAS = (0.5, 0.9)


@dataclass
class SkeletonGANConfig(MethodConfig):
    """SkeletonGAN hyper-parameters (assumed as documented in the module)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "demo": {"hidden": 64, "decoder_hidden": 256, "critic_hidden": 128, "fc": 256,
                 "batch_size": 32, "pretrain_iters": 300, "lr": 5e-4},
        "tiny": {"hidden": 8, "latent": 4, "decoder_hidden": 16, "critic_hidden": 16,
                 "fc": 16, "batch_size": 8, "pretrain_iters": 2, "critic_steps": 1},
    }

    batch_size: int = 64
    latent: int = 12
    hidden: int = 256  # units of the sequence LSTM and of the discriminator's LSTM
    decoder_hidden: int = 1024
    critic_hidden: int = 1024
    fc: int = 1024  # FC layer of the discriminator
    pretrain_iters: int = 10_000
    critic_steps: int = 5
    gp_weight: float = 10.0
    pretrain_lr: float = 1e-3
    lr: float = 1e-4
    shift_weight: float = 0.1  # on Σ ||Δz_t||²
    pose_smoothness: float = 1e-4  # on Σ ||x_{t+1} - x_t||²

    def validate(self) -> None:
        super().validate()
        if min(self.latent, self.hidden, self.decoder_hidden, self.critic_hidden, self.fc,
               self.critic_steps) < 1:
            raise ValueError("SkeletonGANConfig sizes and critic_steps must be >= 1")


@register_method("skeleton_gan")
class SkeletonGAN(PoseVectors, Method):
    """Pretrained single-pose WGAN-GP generator driven by an LSTM of latent shifts."""

    Config = SkeletonGANConfig

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "pose_generator": FrameDecoder(cfg.latent, classes, pose, cfg.decoder_hidden),
            "pose_critic": FrameCritic(pose, classes, cfg.critic_hidden),
            "sequence_generator": LatentTransitions(cfg.latent + classes, cfg.hidden, cfg.latent),
            "discriminator": SequenceLSTM(pose, classes, 1, cfg.hidden, cfg.fc),
        }

    def build_optimizers(self):
        cfg, nets = self.config, self.networks
        return {
            "pose_generator": adam([nets["pose_generator"]], cfg.pretrain_lr, BETAS),
            "pose_critic": adam([nets["pose_critic"]], cfg.pretrain_lr, BETAS),
            "sequence_generator": adam([nets["sequence_generator"]], cfg.lr, BETAS),
            "discriminator": adam([nets["discriminator"]], cfg.lr, BETAS),
        }

    def train_step(self, batch, generator):
        classes = one_hot(batch["label"], len(self.actions))
        if self.iteration < self.config.pretrain_iters:
            return frame_wgan_gp_step(
                self.networks["pose_generator"], self.networks["pose_critic"],
                self.optimizers["pose_generator"], self.optimizers["pose_critic"],
                batch["pose"], classes, generator, self.config.latent,
                self.config.critic_steps, self.config.gp_weight)
        return self._sequence_step(batch["pose"], classes, generator)

    def _generate(self, classes: torch.Tensor, frames: int, generator: torch.Generator):
        """Return latents ``(B, T, L)`` and poses ``(B, T, F)`` for class rows ``(B, C)``."""
        first = latent_prior(len(classes), self.config.latent, generator)
        inputs = torch.cat([first, classes], dim=-1)[:, None].expand(-1, frames - 1, -1)
        latents = self.networks["sequence_generator"](first, inputs)
        poses = self.networks["pose_generator"](latents, classes[:, None].expand(-1, frames, -1))
        return latents, poses

    def _sequence_step(self, real, classes, generator):
        cfg = self.config
        pose_generator, disc = self.networks["pose_generator"], self.networks["discriminator"]
        pose_generator.eval()
        pose_generator.requires_grad_(False)
        latents, fake = self._generate(classes, real.shape[1], generator)

        d_loss = bce(disc(real, classes), 1.0) + bce(disc(fake.detach(), classes), 0.0)
        self.optimizers["discriminator"].zero_grad()
        d_loss.backward()
        self.optimizers["discriminator"].step()

        disc.requires_grad_(False)
        adversarial = bce(disc(fake, classes), 1.0)
        smooth = cfg.shift_weight * smoothness(latents) + cfg.pose_smoothness * smoothness(fake)
        g_loss = adversarial + smooth
        self.optimizers["sequence_generator"].zero_grad()
        g_loss.backward()
        self.optimizers["sequence_generator"].step()
        disc.requires_grad_(True)
        pose_generator.requires_grad_(True)
        return {"d": d_loss.item(), "g": adversarial.item(), "smooth": smooth.item()}

    def generate(self, labels, frames, generator):
        classes = one_hot(labels, len(self.actions))
        return self.poses_to_joints(self._generate(classes, frames, generator)[1])

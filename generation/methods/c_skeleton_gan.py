"""c-SkeletonGAN (seed 003): smooth latent transitions, a shared frame decoder, a bidirectional GAN.

Generator ``G(y, ξ)`` (Eq. 2-3): an *implicit LSTM* (256 units) reads fresh noise
``ξ_t`` (64) and the class row ``y`` at every step and outputs latent shifts
``v_t``; the latent path is ``h_{t+1} = h_t + v_t`` (12-d); each ``h_t`` is decoded by
the shared frame decoder ``x_t = Dec(h_t, y)`` ([code]: ``12 + C -> 1024 -> BN -> ReLU
-> pose``). Dec is pretrained as a conditional WGAN-GP on single frames (Eq. 7,
λ = 10, lr 1e-3) and frozen while the sequence model trains ([code]).

Sequence training (Eq. 4-6, Algorithm 1): a discriminator ``D(x, y)`` and a
classifier ``C(x)``, both a bidirectional LSTM -> FC 1024 -> output; loss of G and C:
GAN term + ``Ω = Σ_t σ1||h_t - h_{t-1}||² + σ2||x_t - x_{t-1}||²`` (σ1 = 0.05,
σ2 = 5e-5) + ``γ (CE(C(x), y) + CE(C(G(y, ξ)), y))`` (γ = 0.1): C also learns from real
data. Adam lr 1e-4. Soft labels ``y = Σ λ_k y_k`` give mixed actions (``mix``).

Choices where paper and code leave room, documented here:

- the first ``fit`` iterations (``pretrain_iters``) pretrain Dec, the rest train the
  sequence model; the iteration counter in the checkpoint tells which phase resumes.
  Each pretraining iteration is ``critic_steps`` = 5 critic updates and one decoder
  update ([code]), on one random frame per clip of the batch;
- ``p_h`` and the first latent ``h_1`` are standard Gaussian (the paper's example; the
  code draws uniform(-1, 1)); shifts are not clipped (the code clips them to [-1, 1]);
- the frozen decoder runs in evaluation mode, so its batch normalisation uses the
  statistics of pretraining, and a motion does not depend on its batch;
- ``real_label="data"`` (default; Algorithm 1 and [code]): D sees real clips with their
  data labels and generated clips with the labels they were generated from, both
  one-hot; ``"classifier"`` (an option, Eq. 5): D's real pair is ``(x, softmax C(x))``
  and C is also trained adversarially to make it look fake. Under ``"classifier"`` the
  real pairs carry soft rows and the fake pairs one-hot rows, so D can tell them apart
  by the label's format alone;
- GAN terms are non-saturating binary cross-entropy; one D update, then one G/C update;
- D and C read ``(x_t, x_{t+1} - x_t)`` per step (D also ``y``), as in the code; their
  head reads the last forward and first backward LSTM states (the code concatenates
  all steps, tying the networks to one length), LSTM 256 units ([code]);
- Adam betas (0.5, 0.9) ([code]); batch 64 ([code]).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
import torch.nn.functional as F

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, adam, one_hot
from generation.methods.seq_gan_common import (
    FrameCritic,
    FrameDecoder,
    LatentTransitions,
    SequenceLSTM,
    SoftLabelSampling,
    bce,
    class_rows,
    frame_wgan_gp_step,
    latent_prior,
    smoothness,
)

BETAS = (0.5, 0.9)


@dataclass
class CSkeletonGANConfig(MethodConfig):
    """c-SkeletonGAN hyper-parameters (seed 003 and its code)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "demo": {"hidden": 64, "decoder_hidden": 256, "critic_hidden": 128, "fc": 256,
                 "batch_size": 32, "pretrain_iters": 300, "lr": 5e-4},
        "tiny": {"hidden": 8, "noise": 4, "latent": 4, "decoder_hidden": 16,
                 "critic_hidden": 16, "fc": 16, "batch_size": 8, "pretrain_iters": 2,
                 "critic_steps": 1},
    }

    batch_size: int = 64
    latent: int = 12  # size of h_t
    noise: int = 64  # size of ξ_t
    hidden: int = 256  # units of the implicit LSTM and of D's and C's LSTMs
    decoder_hidden: int = 1024
    critic_hidden: int = 1024
    fc: int = 1024  # FC layer of D and C
    pretrain_iters: int = 10_000  # iterations of frame WGAN-GP before sequence training
    critic_steps: int = 5
    gp_weight: float = 10.0  # λ
    pretrain_lr: float = 1e-3
    lr: float = 1e-4
    sigma_latent: float = 0.05  # σ1
    sigma_pose: float = 5e-5  # σ2
    gamma: float = 0.1  # weight of the classification (cycle-consistency) terms
    real_label: str = "data"  # "data": Algorithm 1 and code; "classifier": Eq. 5

    def validate(self) -> None:
        super().validate()
        if min(self.latent, self.noise, self.hidden, self.decoder_hidden, self.critic_hidden,
               self.fc, self.critic_steps) < 1:
            raise ValueError("CSkeletonGANConfig sizes and critic_steps must be >= 1")
        if self.real_label not in ("classifier", "data"):
            raise ValueError(
                f"CSkeletonGANConfig.real_label must be 'classifier' or 'data'; got {self.real_label!r}"
            )


@register_method("c_skeleton_gan")
class CSkeletonGAN(SoftLabelSampling, PoseVectors, Method):
    """Implicit LSTM of latent shifts, frozen pretrained frame decoder, D and C bi-LSTMs."""

    Config = CSkeletonGANConfig

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "decoder": FrameDecoder(cfg.latent, classes, pose, cfg.decoder_hidden),
            "frame_critic": FrameCritic(pose, classes, cfg.critic_hidden),
            "transitions": LatentTransitions(cfg.noise + classes, cfg.hidden, cfg.latent),
            "classifier": SequenceLSTM(pose, classes, classes, cfg.hidden, cfg.fc, conditional=False),
            "discriminator": SequenceLSTM(pose, classes, 1, cfg.hidden, cfg.fc),
        }

    def build_optimizers(self):
        cfg, nets = self.config, self.networks
        return {
            "decoder": adam([nets["decoder"]], cfg.pretrain_lr, BETAS),
            "frame_critic": adam([nets["frame_critic"]], cfg.pretrain_lr, BETAS),
            "generator": adam([nets["transitions"], nets["classifier"]], cfg.lr, BETAS),
            "discriminator": adam([nets["discriminator"]], cfg.lr, BETAS),
        }

    def train_step(self, batch, generator):
        classes = one_hot(batch["label"], len(self.actions))
        if self.iteration < self.config.pretrain_iters:
            return frame_wgan_gp_step(
                self.networks["decoder"], self.networks["frame_critic"],
                self.optimizers["decoder"], self.optimizers["frame_critic"], batch["pose"],
                classes, generator, self.config.latent, self.config.critic_steps,
                self.config.gp_weight)
        return self._sequence_step(batch["pose"], batch["label"], classes, generator)

    def _generate(self, classes: torch.Tensor, frames: int, generator: torch.Generator):
        """Return latents ``(B, T, L)`` and poses ``(B, T, F)`` for class rows ``(B, C)``."""
        size = len(classes)
        first = latent_prior(size, self.config.latent, generator)
        noise = torch.randn(size, frames - 1, self.config.noise, generator=generator)
        inputs = torch.cat([noise, classes[:, None].expand(-1, frames - 1, -1)], dim=-1)
        latents = self.networks["transitions"](first, inputs)
        poses = self.networks["decoder"](latents, classes[:, None].expand(-1, frames, -1))
        return latents, poses

    def _sequence_step(self, real, labels, classes, generator):
        cfg = self.config
        decoder, disc, clf = (self.networks[k] for k in ("decoder", "discriminator", "classifier"))
        decoder.eval()
        decoder.requires_grad_(False)
        latents, fake = self._generate(classes, real.shape[1], generator)

        if cfg.real_label == "classifier":
            with torch.no_grad():
                real_rows = F.softmax(clf(real), dim=-1)
        else:
            real_rows = classes
        d_loss = bce(disc(real, real_rows), 1.0) + bce(disc(fake.detach(), classes), 0.0)
        self.optimizers["discriminator"].zero_grad()
        d_loss.backward()
        self.optimizers["discriminator"].step()

        disc.requires_grad_(False)
        real_logits = clf(real)
        adversarial = bce(disc(fake, classes), 1.0)
        if cfg.real_label == "classifier":
            # C plays against D too (Eq. 5): its label should make the real pair look fake.
            adversarial = adversarial + bce(disc(real, F.softmax(real_logits, dim=-1)), 0.0)
        omega = cfg.sigma_latent * smoothness(latents) + cfg.sigma_pose * smoothness(fake)
        cycle = F.cross_entropy(real_logits, labels) + F.cross_entropy(clf(fake), labels)
        g_loss = adversarial + omega + cfg.gamma * cycle
        self.optimizers["generator"].zero_grad()
        g_loss.backward()
        self.optimizers["generator"].step()
        disc.requires_grad_(True)
        decoder.requires_grad_(True)
        return {"d": d_loss.item(), "g": adversarial.item(), "omega": omega.item(),
                "ce": cycle.item()}

    def generate(self, labels, frames, generator, mix=None):
        """Sample motions; ``mix`` (action -> weight) replaces every label by that soft label."""
        classes = class_rows(self, labels, mix)
        return self.poses_to_joints(self._generate(classes, frames, generator)[1])

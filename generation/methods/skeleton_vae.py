"""SkeletonVAE (Habibie et al., BMVC 2017), the recurrent VAE baseline of seeds 003/004.

Habibie et al. encode a motion with temporal convolutions (the motion manifold of
Holden et al. 2015) into a sequence of latent Gaussians, put a standard Gaussian
prior on the latents, and synthesise motion with an RNN that combines latent samples
with an encoded control signal. Seeds 003/004 use it for action generation, so here
the control signal is the action (one-hot, or any row of class weights).

- encoder ``q(z_t | x, y)``: ``Conv1d(F + C -> 256, k) -> ReLU -> Conv1d(256 -> 256, k)
  -> ReLU -> Conv1d(256 -> 2L, 1)``, one Gaussian per frame (L = 32);
- control encoder ``E(y) = ReLU(Linear(C -> 64))``;
- decoder: 2-layer LSTM (512) over ``(z_t, E(y))`` -> ``Linear`` -> pose ``x̂_t``;
- loss: the negative ELBO per frame, ``Σ_f (x̂_t - x_t)² + β KL(q(z_t) || N(0, I))``
  averaged over frames and clips (standardised coordinates, β = 1);
- sampling: ``z_t ~ N(0, I)`` independently per frame, decoded with the action.

What was assumed (the paper gives the structure, not these numbers): the widths
above, kernel width 9 frames (about half a second at 16.7 Hz, Holden's 25 frames at
60 Hz scaled down), no temporal pooling, Adam lr 1e-3 and batch 64. Poses are joint
positions relative to the clip's first root position on the floor, standardised.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
from torch import nn

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, gaussian_kl, one_hot


@dataclass
class SkeletonVAEConfig(MethodConfig):
    """SkeletonVAE hyper-parameters (assumed, see the module)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "demo": {"channels": 64, "latent": 16, "control": 16, "hidden": 128, "batch_size": 32},
        "tiny": {"channels": 8, "latent": 4, "control": 4, "hidden": 8, "layers": 1,
                 "kernel": 3, "batch_size": 8},
    }

    batch_size: int = 64
    channels: int = 256  # convolution channels of the encoder
    kernel: int = 9  # temporal width of the encoder's convolutions (odd)
    latent: int = 32  # size of z_t
    control: int = 64  # size of the encoded action E(y)
    hidden: int = 512  # LSTM units of the decoder
    layers: int = 2
    lr: float = 1e-3
    kl_weight: float = 1.0  # β

    def validate(self) -> None:
        super().validate()
        if min(self.channels, self.kernel, self.latent, self.control, self.hidden, self.layers) < 1:
            raise ValueError("SkeletonVAEConfig sizes must be >= 1")
        if self.kernel % 2 == 0:
            raise ValueError(f"SkeletonVAEConfig.kernel must be odd; got {self.kernel}")


class MotionEncoder(nn.Module):
    """Temporal convolutions of ``(x_t, y)`` to per-frame ``(μ_t, log σ²_t)``."""

    def __init__(self, pose: int, classes: int, channels: int, kernel: int, latent: int):
        super().__init__()
        pad = kernel // 2
        self.net = nn.Sequential(
            nn.Conv1d(pose + classes, channels, kernel, padding=pad), nn.ReLU(),
            nn.Conv1d(channels, channels, kernel, padding=pad), nn.ReLU(),
            nn.Conv1d(channels, 2 * latent, 1),
        )

    def forward(self, poses: torch.Tensor, classes: torch.Tensor):
        """Return ``μ`` and ``log σ²`` ``(B, T, L)`` of poses ``(B, T, F)`` and classes ``(B, C)``."""
        condition = classes[:, :, None].expand(-1, -1, poses.shape[1])
        out = self.net(torch.cat([poses.transpose(1, 2), condition], dim=1)).transpose(1, 2)
        return out.chunk(2, dim=-1)


class MotionDecoder(nn.Module):
    """LSTM of latent samples and the encoded control signal to poses."""

    def __init__(self, latent: int, classes: int, control: int, hidden: int, layers: int, pose: int):
        super().__init__()
        self.control = nn.Sequential(nn.Linear(classes, control), nn.ReLU())
        self.lstm = nn.LSTM(latent + control, hidden, num_layers=layers, batch_first=True)
        self.output = nn.Linear(hidden, pose)

    def forward(self, latents: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        """Return poses ``(B, T, F)`` of latents ``(B, T, L)`` and classes ``(B, C)``."""
        control = self.control(classes)[:, None].expand(-1, latents.shape[1], -1)
        return self.output(self.lstm(torch.cat([latents, control], dim=-1))[0])


@register_method("skeleton_vae")
class SkeletonVAE(PoseVectors, Method):
    """Recurrent VAE: convolutional encoder, per-frame Gaussian latents, LSTM decoder."""

    Config = SkeletonVAEConfig

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "encoder": MotionEncoder(pose, classes, cfg.channels, cfg.kernel, cfg.latent),
            "decoder": MotionDecoder(cfg.latent, classes, cfg.control, cfg.hidden, cfg.layers, pose),
        }

    def build_optimizers(self):
        params = [p for net in self.networks.values() for p in net.parameters()]
        return {"adam": torch.optim.Adam(params, lr=self.config.lr)}

    def train_step(self, batch, generator):
        poses = batch["pose"]
        classes = one_hot(batch["label"], len(self.actions))
        mu, logvar = self.networks["encoder"](poses, classes)
        latents = mu + torch.exp(0.5 * logvar) * torch.randn(mu.shape, generator=generator)
        recon = ((self.networks["decoder"](latents, classes) - poses) ** 2).sum(-1).mean()
        zeros = torch.zeros_like(mu)
        kl = gaussian_kl(mu.flatten(0, 1), logvar.flatten(0, 1), zeros.flatten(0, 1),
                         zeros.flatten(0, 1))
        loss = recon + self.config.kl_weight * kl
        optimizer = self.optimizers["adam"]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        return {"recon": recon.item(), "kl": kl.item()}

    def generate(self, labels, frames, generator):
        classes = one_hot(labels, len(self.actions))
        latents = torch.randn(len(labels), frames, self.config.latent, generator=generator)
        return self.poses_to_joints(self.networks["decoder"](latents, classes))

"""Act-MoCoGAN, a baseline of Action2Motion (seed 000, Sec. 4.2.2), after MoCoGAN (Tulyakov 2018).

MoCoGAN's architecture with its image and video discriminators turned into pose and
motion discriminators. A motion of action ``a`` (one-hot) is drawn as:

- content ``z_C ~ N(0, I)``, one per motion, repeated over its frames;
- motion codes ``z_M(t) = GRU(ε_t, z_M(t-1))`` with ``ε_t ~ N(0, I)`` and
  ``z_M(0) ~ N(0, I)``;
- pose ``p_t = G_I(z_C, a, z_M(t))``, the same frame generator for every frame.

The pose discriminator ``D_I`` sees single frames, the motion discriminator ``D_V``
whole motions. Both are standard GAN discriminators (binary cross-entropy, generator
with the non-saturating loss) with an auxiliary action classifier: each discriminator
also outputs class logits, trained with cross-entropy on real motions, and the
generator is trained to make its motions classified as their action (MoCoGAN's
"InfoGAN" term, the action classification loss seed 000 mentions).

Settings from MoCoGAN's paper and code: ``z_C`` 50, ``ε_t`` and ``z_M`` 10, Adam lr 2e-4,
β = (0.5, 0.999), weight decay 1e-5; one update of each discriminator, then of the
generator, per iteration. Documented choices where neither says:

- ``G_I`` is an MLP (two hidden layers of 128, leaky ReLU) instead of MoCoGAN's image
  deconvolutions; ``D_I`` an MLP of the same widths; ``D_V`` Action2Motion's motion
  discriminator (GRU 128 -> 30 -> outputs); poses as in
  :class:`~generation.methods.common.PoseVectors`;
- ``D_V`` sees the whole training length (Action2Motion's code does so too; MoCoGAN
  sees 16-frame clips); ``D_I`` one random frame of each motion of the batch;
- fake motions are drawn for the actions of the real batch, so classes stay balanced
  as in the data; the batch is A2M's 128;
- MoCoGAN's image discriminator has no class output; ``pose_categories=False`` restores
  that, the default conditions both discriminators as the adaptation asks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
import torch.nn.functional as F
from torch import nn

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, adam, one_hot
from generation.methods.gan_common import (
    MotionDiscriminator,
    PoseDiscriminator,
    mlp,
    random_frames,
    set_trainable,
)


@dataclass
class ActMoCoGANConfig(MethodConfig):
    """Act-MoCoGAN hyper-parameters (MoCoGAN's where it has them; see the module docstring)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        # Small enough to train in about a minute on a laptop CPU (``make demo``).
        "demo": {"hidden": 64, "batch_size": 32, "lr": 5e-4},
        "tiny": {"hidden": 16, "content": 4, "motion": 3, "batch_size": 8},
    }

    batch_size: int = 128
    hidden: int = 128  # width of the frame generator and of both discriminators
    content: int = 50  # z_C
    motion: int = 10  # ε_t and z_M (MoCoGAN's GRU maps 10 -> 10)
    lr: float = 2e-4
    beta1: float = 0.5
    beta2: float = 0.999
    weight_decay: float = 1e-5
    category_weight: float = 1.0  # weight of the action classification terms
    pose_categories: bool = True  # the pose discriminator classifies actions too

    def validate(self) -> None:
        super().validate()
        if min(self.hidden, self.content, self.motion) < 1:
            raise ValueError("ActMoCoGANConfig sizes (hidden, content, motion) must be >= 1")
        if not (0.0 <= self.beta1 < 1.0 and 0.0 <= self.beta2 < 1.0):
            raise ValueError("ActMoCoGANConfig.beta1 and beta2 must be in [0, 1)")


class MotionContentGenerator(nn.Module):
    """MoCoGAN's generator: content + action + GRU motion codes -> per-frame pose MLP."""

    def __init__(self, content: int, motion: int, classes: int, hidden: int, pose: int):
        super().__init__()
        self.content, self.motion = content, motion
        self.recurrent = nn.GRUCell(motion, motion)
        self.frame = mlp([content + classes + motion, hidden, hidden, pose])

    def forward(self, classes: torch.Tensor, frames: int, generator: torch.Generator):
        """Return poses ``(N, frames, F)`` of actions ``(N, C)``, noise from ``generator``."""
        size = len(classes)
        content = torch.randn(size, self.content, generator=generator)
        state = torch.randn(size, self.motion, generator=generator)
        steps = torch.randn(frames, size, self.motion, generator=generator)
        codes = []
        for step in steps:
            state = self.recurrent(step, state)
            codes.append(state)
        codes = torch.stack(codes, dim=1)
        fixed = torch.cat([content, classes], dim=-1)[:, None, :].expand(-1, frames, -1)
        return self.frame(torch.cat([fixed, codes], dim=-1))


@register_method("act_mocogan")
class ActMoCoGAN(PoseVectors, Method):
    """MoCoGAN for actions: content and motion noise, pose and motion discriminators."""

    Config = ActMoCoGANConfig

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "generator": MotionContentGenerator(cfg.content, cfg.motion, classes, cfg.hidden, pose),
            "pose_discriminator": PoseDiscriminator(
                pose, 0, cfg.hidden, 1 + (classes if cfg.pose_categories else 0)),
            "motion_discriminator": MotionDiscriminator(pose, 0, cfg.hidden, 1 + classes),
        }

    def build_optimizers(self):
        cfg = self.config
        return {key: adam([net], cfg.lr, (cfg.beta1, cfg.beta2), cfg.weight_decay)
                for key, net in self.networks.items()}

    def _scores(self, key: str, inputs: torch.Tensor):
        """Return real/fake logits ``(N,)`` and class logits ``(N, C)`` or None."""
        out = self.networks[key](inputs)
        return out[:, 0], (out[:, 1:] if out.shape[1] > 1 else None)

    def _discriminator_step(self, key: str, real, fake, labels) -> float:
        real_logit, real_classes = self._scores(key, real)
        fake_logit, _ = self._scores(key, fake.detach())
        loss = (F.binary_cross_entropy_with_logits(real_logit, torch.ones_like(real_logit))
                + F.binary_cross_entropy_with_logits(fake_logit, torch.zeros_like(fake_logit)))
        if real_classes is not None:
            loss = loss + self.config.category_weight * F.cross_entropy(real_classes, labels)
        optimizer = self.optimizers[key]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        return loss.item()

    def _generator_loss(self, key: str, fake, labels) -> torch.Tensor:
        logit, classes = self._scores(key, fake)
        loss = F.binary_cross_entropy_with_logits(logit, torch.ones_like(logit))
        if classes is not None:
            loss = loss + self.config.category_weight * F.cross_entropy(classes, labels)
        return loss

    def train_step(self, batch, generator):
        real, labels = batch["pose"], batch["label"]
        fake = self.networks["generator"](one_hot(labels, len(self.actions)), real.shape[1],
                                          generator)
        real_frames, fake_frames = random_frames(real, generator), random_frames(fake, generator)
        losses = {
            "pose_d": self._discriminator_step("pose_discriminator", real_frames, fake_frames,
                                               labels),
            "motion_d": self._discriminator_step("motion_discriminator", real, fake, labels),
        }
        discriminators = [self.networks[key] for key in ("pose_discriminator",
                                                         "motion_discriminator")]
        set_trainable(discriminators, False)
        loss = (self._generator_loss("pose_discriminator", fake_frames, labels)
                + self._generator_loss("motion_discriminator", fake, labels))
        optimizer = self.optimizers["generator"]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        set_trainable(discriminators, True)
        losses["generator"] = loss.item()
        return losses

    def generate(self, labels, frames, generator):
        poses = self.networks["generator"](one_hot(labels, len(self.actions)), frames, generator)
        return self.poses_to_joints(poses)

"""Two-stage GAN, a baseline of Action2Motion (seed 000, Sec. 4.2.2), after Cai et al. 2018.

Stage 1, a pose GAN: a pose generator ``G_p(z, a)`` maps noise ``z ~ N(0, I)`` and the
one-hot action ``a`` to a single pose; it is trained as a conditional WGAN-GP against a
pose critic ``D_p(p, a)`` on single real frames.

Stage 2, a motion GAN: ``G_p`` is frozen; a motion generator (a GRU fed fresh noise
``ε_t`` and ``a`` at every step) outputs one noise vector ``z_t`` per frame, and
``G_p(z_t, a)`` turns it into the pose of frame ``t``. The motion generator is trained as
a conditional WGAN-GP against a motion critic ``D_m(p_{1:T}, a)`` (a GRU over the whole
sequence), which is what enforces temporal coherence.

Neither seed 000 nor Cai et al. give sizes for this adaptation; documented choices:

- poses are joint positions (see :class:`~generation.methods.common.PoseVectors`), so the
  method works alike in 3D and 2D ("necessary modifications ... to work in 3D");
- widths as A2M's (128): ``G_p`` and ``D_p`` are MLPs with two hidden layers of 128 and
  leaky ReLUs, no batch normalisation (a frozen generator then behaves the same in
  training and sampling, and WGAN-GP critics must not mix samples); ``z`` has 32
  dimensions, ``ε_t`` 32; the motion generator is a one-layer GRU of 128 with a linear
  output, the motion critic A2M's motion discriminator (GRU 128 -> 30 -> 1);
- WGAN-GP settings of Gulrajani et al. 2017: penalty weight 10, 5 critic updates per
  generator update, Adam lr 1e-4, β = (0.5, 0.9);
- a stage-1 iteration takes every frame of the batch's clips as its real poses (many
  poses per update, cheap for MLPs); the critic updates of an iteration reuse the real
  batch, each with fresh noise;
- stage 1 runs for the first ``pose_iterations`` iterations (10,000 by default), stage 2
  for the rest, so ``fit`` can stop and resume in either stage.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
from torch import nn

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, adam, one_hot
from generation.methods.gan_common import (
    MotionDiscriminator,
    PoseDiscriminator,
    mlp,
    set_trainable,
    wgan_critic_step,
)


@dataclass
class TwoStageGANConfig(MethodConfig):
    """Two-stage GAN hyper-parameters (documented choices; see the module docstring)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        # Small enough to train in about a minute on a laptop CPU (``make demo``, 400 iterations).
        "demo": {"hidden": 64, "batch_size": 32, "pose_iterations": 250, "lr": 1e-3},
        "tiny": {"hidden": 16, "noise": 4, "step_noise": 4, "batch_size": 8,
                 "pose_iterations": 2, "critic_steps": 1},
    }

    batch_size: int = 128
    hidden: int = 128  # width of every network
    noise: int = 32  # z, the pose generator's input (what the motion generator outputs per frame)
    step_noise: int = 32  # ε_t, the motion generator's fresh noise per frame
    pose_iterations: int = 10_000  # stage 1 (pose GAN) length; stage 2 follows
    critic_steps: int = 5
    gp_weight: float = 10.0
    lr: float = 1e-4
    beta1: float = 0.5
    beta2: float = 0.9

    def validate(self) -> None:
        super().validate()
        if min(self.hidden, self.noise, self.step_noise, self.critic_steps) < 1:
            raise ValueError(
                "TwoStageGANConfig sizes (hidden, noise, step_noise, critic_steps) must be >= 1")
        if not (0.0 <= self.beta1 < 1.0 and 0.0 <= self.beta2 < 1.0):
            raise ValueError("TwoStageGANConfig.beta1 and beta2 must be in [0, 1)")


class PoseGenerator(nn.Module):
    """(z, action) -> MLP -> pose vector."""

    def __init__(self, noise: int, classes: int, hidden: int, pose: int):
        super().__init__()
        self.net = mlp([noise + classes, hidden, hidden, pose])

    def forward(self, z: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        """Return poses ``(..., F)`` of noise ``(..., Z)`` and one-hot actions ``(..., C)``."""
        return self.net(torch.cat([z, classes], dim=-1))


class NoiseSequencer(nn.Module):
    """The motion generator: (ε_t, action) -> GRU -> linear -> z_t for the pose generator."""

    def __init__(self, step_noise: int, classes: int, hidden: int, noise: int):
        super().__init__()
        self.gru = nn.GRU(step_noise + classes, hidden, batch_first=True)
        self.output = nn.Linear(hidden, noise)

    def forward(self, steps: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        """Return ``z_{1:T}`` ``(N, T, Z)`` of step noise ``(N, T, E)`` and actions ``(N, C)``."""
        condition = classes[:, None, :].expand(-1, steps.shape[1], -1)
        hidden, _ = self.gru(torch.cat([steps, condition], dim=-1))
        return self.output(hidden)


@register_method("two_stage_gan")
class TwoStageGAN(PoseVectors, Method):
    """Pose WGAN, then a motion generator that drives the frozen pose generator with noise."""

    Config = TwoStageGANConfig

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "pose_generator": PoseGenerator(cfg.noise, classes, cfg.hidden, pose),
            "pose_critic": PoseDiscriminator(pose, classes, cfg.hidden),
            "motion_generator": NoiseSequencer(cfg.step_noise, classes, cfg.hidden, cfg.noise),
            "motion_critic": MotionDiscriminator(pose, classes, cfg.hidden),
        }

    def build_optimizers(self):
        betas = (self.config.beta1, self.config.beta2)
        return {key: adam([net], self.config.lr, betas) for key, net in self.networks.items()}

    @property
    def stage(self) -> int:
        """Return the stage the next training iteration is in: 1 (poses) or 2 (motions)."""
        return 1 if self.iteration < self.config.pose_iterations else 2

    def train_step(self, batch, generator):
        classes = one_hot(batch["label"], len(self.actions))
        if self.stage == 1:
            frames = batch["pose"].shape[1]
            return self._pose_step(batch["pose"].flatten(0, 1),
                                   classes.repeat_interleave(frames, dim=0), generator)
        return self._motion_step(batch["pose"], classes, generator)

    def _adversarial_step(self, generate, critic_key: str, generator_key: str, real, classes,
                          generator) -> dict[str, float]:
        """Run the critic updates then one generator update; ``generate()`` draws fakes."""
        cfg = self.config
        critic = self.networks[critic_key]
        set_trainable([critic], True)
        for _ in range(cfg.critic_steps):
            with torch.no_grad():
                fake = generate()
            distance = wgan_critic_step(critic, self.optimizers[critic_key], real, fake,
                                        generator, cfg.gp_weight, classes)
        set_trainable([critic], False)
        loss = -critic(generate(), classes).mean()
        optimizer = self.optimizers[generator_key]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        set_trainable([critic], True)
        return {"critic": distance, "generator": loss.item()}

    def _pose_step(self, real, classes, generator):
        pose_generator = self.networks["pose_generator"]
        set_trainable([pose_generator], True)

        def generate():
            noise = torch.randn(len(real), self.config.noise, generator=generator)
            return pose_generator(noise, classes)

        losses = self._adversarial_step(generate, "pose_critic", "pose_generator", real, classes,
                                        generator)
        return {f"pose_{key}": value for key, value in losses.items()}

    def _motion_step(self, real, classes, generator):
        set_trainable([self.networks["pose_generator"]], False)  # frozen in stage 2

        def generate():
            return self._motions(classes, real.shape[1], generator)

        losses = self._adversarial_step(generate, "motion_critic", "motion_generator", real,
                                        classes, generator)
        return {f"motion_{key}": value for key, value in losses.items()}

    def _motions(self, classes: torch.Tensor, frames: int, generator: torch.Generator):
        """Return pose vectors ``(N, frames, F)`` for one-hot actions ``(N, C)``."""
        steps = torch.randn(len(classes), frames, self.config.step_noise, generator=generator)
        z = self.networks["motion_generator"](steps, classes)
        return self.networks["pose_generator"](z, classes[:, None, :].expand(-1, frames, -1))

    def generate(self, labels, frames, generator):
        classes = one_hot(labels, len(self.actions))
        poses = self._motions(classes, frames, generator)
        return self.poses_to_joints(poses)

"""Pieces shared by the GAN methods: discriminators, WGAN-GP, frame picking.

Every GAN here models a motion as a sequence of pose vectors: joint positions relative
to the clip's first root position on the floor (height kept), standardised per
coordinate over the training frames (:class:`~generation.methods.common.PoseVectors`).
Samples are placed at the training clips' mean start.

This module defines no method; it is imported with the method modules and registers
nothing.
"""

from __future__ import annotations

from typing import Iterable

import torch
from torch import nn

# Width of the last hidden layer of the motion discriminator (as in Action2Motion's code).
MOTION_HEAD = 30


def mlp(sizes: list[int], slope: float = 0.2) -> nn.Sequential:
    """Return linear layers of ``sizes`` with leaky ReLUs between them (none after the last)."""
    layers: list[nn.Module] = []
    for i, (inputs, outputs) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(inputs, outputs))
        if i < len(sizes) - 2:
            layers.append(nn.LeakyReLU(slope))
    return nn.Sequential(*layers)


class PoseDiscriminator(nn.Module):
    """An MLP over one pose, optionally with a condition (e.g. one-hot action) appended.

    No batch normalisation, so that it can serve as a WGAN-GP critic (the penalty is per
    sample).
    """

    def __init__(self, pose: int, condition: int, hidden: int, outputs: int = 1, layers: int = 2):
        super().__init__()
        self.net = mlp([pose + condition] + [hidden] * layers + [outputs])

    def forward(self, poses: torch.Tensor, condition: torch.Tensor | None = None) -> torch.Tensor:
        """Return scores ``(N, outputs)`` of poses ``(N, F)`` and conditions ``(N, C)``."""
        if condition is not None:
            poses = torch.cat([poses, condition], dim=-1)
        return self.net(poses)


class MotionDiscriminator(nn.Module):
    """A GRU over a pose sequence, then ``Linear -> tanh -> Linear`` on its last output.

    The structure of Action2Motion's motion discriminator; the condition, if any, is
    appended to every frame.
    """

    def __init__(self, pose: int, condition: int, hidden: int, outputs: int = 1, layers: int = 1):
        super().__init__()
        self.gru = nn.GRU(pose + condition, hidden, num_layers=layers, batch_first=True)
        self.head = nn.Sequential(nn.Linear(hidden, MOTION_HEAD), nn.Tanh(),
                                  nn.Linear(MOTION_HEAD, outputs))

    def forward(self, motions: torch.Tensor, condition: torch.Tensor | None = None) -> torch.Tensor:
        """Return scores ``(N, outputs)`` of motions ``(N, T, F)`` and conditions ``(N, C)``."""
        if condition is not None:
            motions = torch.cat(
                [motions, condition[:, None, :].expand(-1, motions.shape[1], -1)], dim=-1)
        hidden, _ = self.gru(motions)
        return self.head(hidden[:, -1])


def gradient_penalty(critic: nn.Module, real: torch.Tensor, fake: torch.Tensor,
                     generator: torch.Generator, *inputs) -> torch.Tensor:
    """Return the WGAN-GP penalty ``E[(||∇ critic(x̂)|| - 1)²]`` on random interpolates.

    ``x̂ = α real + (1 - α) fake`` with one ``α ~ U(0, 1)`` per sample; ``inputs`` (the
    condition) are passed to the critic unchanged.
    """
    alpha = torch.rand((real.shape[0],) + (1,) * (real.dim() - 1), generator=generator)
    mixed = (alpha * real + (1 - alpha) * fake.detach()).requires_grad_(True)
    (grad,) = torch.autograd.grad(critic(mixed, *inputs).sum(), mixed, create_graph=True)
    return ((grad.flatten(1).norm(dim=1) - 1) ** 2).mean()


def wgan_critic_step(critic: nn.Module, optimizer: torch.optim.Optimizer, real: torch.Tensor,
                     fake: torch.Tensor, generator: torch.Generator, gp_weight: float,
                     *inputs) -> float:
    """Update a WGAN-GP critic once; return its Wasserstein estimate ``E[D(real)] - E[D(fake)]``."""
    fake = fake.detach()
    distance = critic(real, *inputs).mean() - critic(fake, *inputs).mean()
    loss = -distance + gp_weight * gradient_penalty(critic, real, fake, generator, *inputs)
    optimizer.zero_grad()
    loss.backward()
    optimizer.step()
    return distance.item()


def random_frames(motions: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Return one random frame ``(N, F)`` of each motion ``(N, T, F)``."""
    index = torch.randint(motions.shape[1], (motions.shape[0],), generator=generator)
    return motions[torch.arange(motions.shape[0]), index]


def set_trainable(networks: Iterable[nn.Module], flag: bool) -> None:
    """Switch gradients of the networks' parameters on or off (off while others train)."""
    for net in networks:
        for param in net.parameters():
            param.requires_grad_(flag)

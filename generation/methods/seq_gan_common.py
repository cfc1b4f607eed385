"""Pieces shared by the baselines of seeds 003/004: soft labels, frame GAN, LSTM critics.

Poses are joint positions relative to the clip's first root position on the floor
(height kept), flattened to ``F = J * D`` numbers and standardised per coordinate over
the training frames (:class:`~generation.methods.common.PoseVectors`); samples are
placed at the training clips' mean start. Class conditions are rows of ``C`` weights:
one-hot for an action, or a soft label mixing several (seed 003, "novel action
generation by mixing action classes"; seed 004 Eq. 8).

This module defines no method; it registers nothing.
"""

from __future__ import annotations

import math
from typing import Mapping

import torch
import torch.nn.functional as F
from torch import nn

from generation.methods.base import Method, MethodError
from generation.methods.common import one_hot

# Joins the names of mixed actions in the action of a mixed motion ("Walking+Phoning").
MIX_JOINER = "+"


def mix_weights(method: Method, mix: Mapping[str, float]) -> dict[str, float]:
    """Return the action weights of a soft label, checked and normalised to sum 1.

    Actions of weight 0 are dropped; names must be the model's actions and weights
    finite and non-negative with a positive sum.
    """
    if not isinstance(mix, Mapping) or not mix:
        raise MethodError(
            f"mix must map action names to weights, e.g. {{{method.actions[0]!r}: 0.5, ...}}; "
            f"got {mix!r}"
        )
    unknown = [name for name in mix if name not in method.actions]
    if unknown:
        raise MethodError(
            f"mix names {', '.join(map(repr, unknown))}, which {method.name} does not know; "
            f"its actions are {', '.join(method.actions)}"
        )
    weights = {}
    for name, weight in mix.items():
        try:
            weight = float(weight)
        except (TypeError, ValueError):
            weight = math.nan
        if not math.isfinite(weight) or weight < 0:
            raise MethodError(
                f"mix weight of {name!r} must be a finite non-negative number; got {mix[name]!r}"
            )
        weights[name] = weight
    total = sum(weights.values())
    if total <= 0:
        raise MethodError(f"mix weights must not all be 0; got {dict(mix)}")
    return {name: weight / total for name, weight in weights.items() if weight > 0}


def class_rows(method: Method, labels: torch.Tensor, mix: Mapping[str, float] | None) -> torch.Tensor:
    """Return conditions ``(N, C)``: one-hot rows of ``labels``, or the soft label of ``mix`` for all."""
    classes = len(method.actions)
    if mix is None:
        return one_hot(labels, classes)
    row = torch.zeros(classes)
    for name, weight in mix_weights(method, mix).items():
        row[method.actions.index(name)] = weight
    return row.expand(len(labels), -1).clone()


class SoftLabelSampling:
    """Mixin for methods whose ``generate`` takes ``mix``: name mixed motions after their actions.

    With ``mix={"Walking": 0.5, "Phoning": 0.5}`` every requested motion is drawn with
    that soft label; its action reads ``"Walking+Phoning"`` and ``meta["mix"]`` holds
    the normalised weights.
    """

    def sample(self, actions, frames=None, seed=0, **options):
        mix = options.get("mix")
        if mix is None:
            return super().sample(actions, frames, seed, **options)
        weights = mix_weights(self, mix)
        motions = super().sample(actions, frames, seed, **options)
        name = MIX_JOINER.join(weights)
        return [m.with_joints(m.joints, action=name, meta={**m.meta, "mix": weights})
                for m in motions]


def bce(logits: torch.Tensor, target: float) -> torch.Tensor:
    """Return the binary cross-entropy of logits against a constant target (1 real, 0 fake)."""
    return F.binary_cross_entropy_with_logits(logits, torch.full_like(logits, target))


def smoothness(sequence: torch.Tensor) -> torch.Tensor:
    """Return ``Σ_t ||s_t - s_{t-1}||²`` of sequences ``(B, T, K)``, mean over the batch."""
    return ((sequence[:, 1:] - sequence[:, :-1]) ** 2).sum(dim=(1, 2)).mean()


def random_frames(poses: torch.Tensor, count: int, generator: torch.Generator) -> torch.Tensor:
    """Return ``count`` frames drawn with replacement from each sequence ``(B, T, F)``: ``(B, count, F)``."""
    size, frames = poses.shape[:2]
    index = torch.randint(frames, (size, count), generator=generator)
    return poses[torch.arange(size)[:, None], index]


class FrameDecoder(nn.Module):
    """Pose of a latent code and class: ``(h, y) -> 1024 -> BN -> ReLU -> pose`` (003 [code])."""

    def __init__(self, latent: int, classes: int, pose: int, hidden: int = 1024):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(latent + classes, hidden), nn.BatchNorm1d(hidden), nn.ReLU(),
            nn.Linear(hidden, pose),
        )

    def forward(self, codes: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        """Return poses ``(..., F)`` of codes ``(..., L)`` and classes ``(..., C)``."""
        shape = codes.shape[:-1]
        inputs = torch.cat([codes, classes], dim=-1).reshape(-1, codes.shape[-1] + classes.shape[-1])
        return self.net(inputs).reshape(shape + (-1,))


class FrameCritic(nn.Module):
    """WGAN critic of single poses: ``(x, y) -> 1024 -> ReLU -> score`` (003 [code])."""

    def __init__(self, pose: int, classes: int, hidden: int = 1024):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(pose + classes, hidden), nn.ReLU(), nn.Linear(hidden, 1))

    def forward(self, poses: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([poses, classes], dim=-1)).squeeze(-1)


def latent_prior(size: int, latent: int, generator: torch.Generator) -> torch.Tensor:
    """Return codes ``(size, latent)`` from p_h, the standard Gaussian (003, Eq. 7)."""
    return torch.randn(size, latent, generator=generator)


def frame_wgan_gp_step(decoder: FrameDecoder, critic: FrameCritic, decoder_opt, critic_opt,
                       poses: torch.Tensor, classes: torch.Tensor, generator: torch.Generator,
                       latent: int, critic_steps: int, gp_weight: float) -> dict[str, float]:
    """Run one conditional WGAN-GP iteration on single frames of a batch ``(B, T, F)``.

    ``critic_steps`` critic updates, each on one random frame per clip, then one
    decoder update (003, Eq. 7; Gulrajani et al. 2017).
    """
    size = len(poses)
    for _ in range(critic_steps):
        real = random_frames(poses, 1, generator)[:, 0]
        with torch.no_grad():
            fake = decoder(latent_prior(size, latent, generator), classes)
        alpha = torch.rand(size, 1, generator=generator)
        between = (real + alpha * (fake - real)).requires_grad_(True)
        grad, = torch.autograd.grad(critic(between, classes).sum(), between, create_graph=True)
        penalty = ((grad.norm(dim=-1) - 1) ** 2).mean()
        distance = critic(real, classes).mean() - critic(fake, classes).mean()
        critic_opt.zero_grad()
        (gp_weight * penalty - distance).backward()
        critic_opt.step()
    loss = -critic(decoder(latent_prior(size, latent, generator), classes), classes).mean()
    decoder_opt.zero_grad()
    loss.backward()
    decoder_opt.step()
    return {"wasserstein": distance.item(), "gp": penalty.item(), "frame_g": loss.item()}


class LatentTransitions(nn.Module):
    """LSTM of per-step inputs to latent shifts: ``v_t = W LSTM(u)_t``, ``h_{t+1} = h_t + v_t``."""

    def __init__(self, inputs: int, hidden: int, latent: int):
        super().__init__()
        self.lstm = nn.LSTM(inputs, hidden, batch_first=True)
        self.shift = nn.Linear(hidden, latent)

    def forward(self, first: torch.Tensor, inputs: torch.Tensor) -> torch.Tensor:
        """Return latents ``(B, S + 1, L)`` from ``h_1`` ``(B, L)`` and inputs ``(B, S, I)``."""
        if inputs.shape[1] == 0:
            return first[:, None]
        shifts = self.shift(self.lstm(inputs)[0])
        return torch.cat([first[:, None], first[:, None] + shifts.cumsum(dim=1)], dim=1)


class SequenceLSTM(nn.Module):
    """Bidirectional LSTM -> FC 1024 -> ReLU -> outputs: 003's discriminator and classifier.

    Step ``t`` reads ``(x_t, x_{t+1} - x_t)`` and, for a discriminator, the class row
    (as in the authors' code); the head reads the last forward and first backward states.
    """

    def __init__(self, pose: int, classes: int, outputs: int, hidden: int = 256,
                 fc: int = 1024, conditional: bool = True):
        super().__init__()
        self.conditional = conditional
        inputs = 2 * pose + (classes if conditional else 0)
        self.lstm = nn.LSTM(inputs, hidden, batch_first=True, bidirectional=True)
        self.head = nn.Sequential(nn.Linear(2 * hidden, fc), nn.ReLU(), nn.Linear(fc, outputs))

    def forward(self, poses: torch.Tensor, classes: torch.Tensor | None = None) -> torch.Tensor:
        """Return outputs ``(B, outputs)`` (squeezed for one) of sequences ``(B, T, F)``, T >= 2."""
        steps = [poses[:, :-1], poses[:, 1:] - poses[:, :-1]]
        if self.conditional:
            steps.append(classes[:, None].expand(-1, poses.shape[1] - 1, -1))
        out = self.lstm(torch.cat(steps, dim=-1))[0]
        half = out.shape[-1] // 2
        summary = torch.cat([out[:, -1, :half], out[:, 0, half:]], dim=-1)
        return self.head(summary).squeeze(-1)
